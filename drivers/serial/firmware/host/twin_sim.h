/*
 * twin_sim.h - the physics behind the HAL of the host build: motor, gear with play, load, encoders.
 *
 * The C port of servoid's twin physics (servoid/drivers/twin/kernel.py and
 * encoder.py), operation for operation: semi-implicit Euler with a fixed
 * sub-step, the winding current advanced exactly over each sub-step, Karnopp
 * stick-slip friction on motor and load, a one-sided spring and damper past
 * the gear's flanks, an efficiency that depends on which side drives.
 *
 * The firmware's loop (../loop.h) is not here: on a board it runs on the
 * control timer; here the simulation is that timer, and calls the loop's
 * ticks at the sub-steps where they fall, handing it the encoders' counts
 * (quantised, with noise) and the measured current, and applying the
 * voltage it asks for. Time advances only when asked (twin_advance), so
 * the host's set points are sample-and-hold on the twin's own grid.
 *
 * Noise: a seeded xorshift generator (one stream per encoder), not NumPy's:
 * with encoder noise the C and Python twins agree in distribution, not
 * sample for sample; without it (the presets' default) they agree exactly.
 */
#ifndef SERVOID_TWIN_SIM_H
#define SERVOID_TWIN_SIM_H

#include <stdint.h>

#include "../loop.h"
#include "../twin_layout.h"

typedef struct {
    double phys[TW_P_SIZE];
    double fw[TW_F_SIZE];
    loop_t loop;               /* the firmware's loop this simulation is the timer of */
    /* bodies and winding */
    double th_m, w_m, th_l, w_l, cur;
    int stuck_m, stuck_l;
    int64_t k;                 /* sub-steps since reset */
    double requested_s;        /* servo time asked for since reset (advance rounds to the sub-step) */
    uint64_t rng_m, rng_l;     /* encoder noise streams */
    uint64_t seed;
    int output_load;           /* the output is read on the load encoder (else the motor's) */
} twin_sim_t;

/* Set up from the packed arrays of servoid.drivers.twin.TwinParams.pack() and which encoder is the
 * output (TwinParams.output_encoder == "load"); then twin_reset(). */
void twin_init(twin_sim_t *t, const double *phys, const double *fw, int output_load, uint64_t seed);
/* Power cycle: at rest at zero, torque off, the loop's power-up tick run (the encoders sampled). */
void twin_reset(twin_sim_t *t);
/* Run dt_s of servo time (added to a running total, rounded to whole sub-steps). */
void twin_advance(twin_sim_t *t, double dt_s);
/* Counts of the output encoder at the loop's latest tick, and that encoder's counts per output turn. */
double twin_output_counts(const twin_sim_t *t);
double twin_output_cpr(const twin_sim_t *t);
/* Change the play (wear), total at the output, rad. */
void twin_set_play(twin_sim_t *t, double play_rad);

#endif
