/*
 * sim_motor.h - the simulated servo behind the host build's HAL: a physical twin, or the backlash model.
 *
 * Two kinds. A twin (twin_sim.h: motor, gear with play, load, encoders) with
 * the firmware's own loop (../loop.h) running at its ticks: one sample is one
 * period of servo time, the period the host set (C request), else
 * SM_DEFAULT_PERIOD_US; with the torque off its drive stage is open and it
 * coasts (reads run the samples due). Or the pseudo-Wiener model, below,
 * for exact transport tests.
 *
 * bl_plant_t is servoid's BacklashModel stepped one sample at a time: the
 * linear block x(k) = -sum a_i x(k-i) + sum b_j u(k-d-j) followed by the
 * backlash (up line y = x - c1, down line y = m2 (x + c2), memory zone in
 * between), exactly as servoid.ident.Plant and servoid.ident.models.simulate (tested
 * sample by sample against them).
 *
 * sim_motor_t runs it as a position loop triggered by the host's set points,
 * with the rules of servoid.drivers.sampled.SampledPlant: each set point is one
 * sample (taken before the set point acts); a set point that comes n periods
 * after the previous one (n >= 2: as the host counts its slots when it says,
 * else from the clock, rounded) is preceded by n - 1 samples on the held set
 * point; a read runs the held samples due up to its time.
 * Positions leave through a quantising encoder (counts_per_unit = cpr / 2 pi).
 */
#ifndef SERVOID_SIM_MOTOR_H
#define SERVOID_SIM_MOTOR_H

#include <stdint.h>

#include "../hal.h"
#include "twin_sim.h"

#define SM_MAX_NA 8
#define SM_MAX_NB 8
#define SM_MAX_DELAY 32
#define SM_DEFAULT_PERIOD_US 5000u /* a twin's sample when the host set no period: servoid's default 200 Hz */

typedef struct {
    int na, nb, delay;
    double a[SM_MAX_NA];
    double b[SM_MAX_NB + 1];
    double m2, c1, c2;
} bl_model_t;

typedef struct {
    bl_model_t m;
    double x_hist[SM_MAX_NA];                 /* x(k-1) .. x(k-na) */
    double u_hist[SM_MAX_DELAY + SM_MAX_NB];  /* u(k-1) .. u(k-delay-nb) */
    double x, y;
} bl_plant_t;

/* NULL when the model is usable, else what is wrong with it. */
const char *bl_model_check(const bl_model_t *m);
void bl_plant_init(bl_plant_t *p, const bl_model_t *m);
void bl_plant_reset(bl_plant_t *p);
/* Apply u(k); return y(k) (which depends on u(k-delay) and earlier). */
double bl_plant_step(bl_plant_t *p, double u);

typedef struct {
    int is_twin;
    twin_sim_t twin;           /* the twin (is_twin) */
    double twin_period_s;      /* servo time per sample */
    double rad_per_count;      /* the twin's set point per count of its output encoder */
    double y_counts;           /* the twin's output reading of the latest sample */
    bl_plant_t plant;          /* the model (!is_twin) */
    double counts_per_unit;
    double noise_std;          /* encoder noise, plant unit, before quantisation */
    uint64_t rng;
    int enabled;
    uint32_t period_us;        /* 0: one sample per set point, whatever the time between */
    int started;               /* a sample was taken since the torque went on / the period changed */
    uint32_t last_us;          /* time of the latest sample */
    int64_t index;             /* latest sample, -1 before the first */
    double held;               /* set point in effect, plant unit */
} sim_motor_t;

void sim_motor_init(sim_motor_t *s, const bl_model_t *m, double counts_per_unit, double noise_std, uint64_t seed);
/* A twin from the packed arrays of TwinParams.pack() (see twin_sim.h). */
void sim_motor_init_twin(sim_motor_t *s, const double *phys, const double *fw, int output_load, uint64_t seed);
void sim_motor_reset(sim_motor_t *s);
void sim_motor_enable(sim_motor_t *s, int on);
void sim_motor_period(sim_motor_t *s, uint32_t period_us);
/* periods: control periods since the previous set point as the host counts them, 0: from the clock */
hal_sample_t sim_motor_command(sim_motor_t *s, int32_t counts, uint32_t periods, uint32_t now_us);
hal_sample_t sim_motor_read(sim_motor_t *s, uint32_t now_us);
/* Nonzero when a twin's loop turned its output stage off by itself (TW_FAULT_*). */
int sim_motor_fault(const sim_motor_t *s);

#endif
