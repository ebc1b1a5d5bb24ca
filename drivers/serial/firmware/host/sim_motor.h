/*
 * sim_motor.h - a simulated motor + gear with backlash, for the host build.
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

#define SM_MAX_NA 8
#define SM_MAX_NB 8
#define SM_MAX_DELAY 32

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
    bl_plant_t plant;
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
void sim_motor_reset(sim_motor_t *s);
void sim_motor_enable(sim_motor_t *s, int on);
void sim_motor_period(sim_motor_t *s, uint32_t period_us);
/* periods: control periods since the previous set point as the host counts them, 0: from the clock */
hal_sample_t sim_motor_command(sim_motor_t *s, int32_t counts, uint32_t periods, uint32_t now_us);
hal_sample_t sim_motor_read(sim_motor_t *s, uint32_t now_us);

#endif
