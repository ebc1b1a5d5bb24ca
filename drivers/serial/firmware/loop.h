/*
 * loop.h - the position loop of the bench controller: the drive's loops, one tick at a time.
 *
 * A board's control timer calls loop_control_tick() at the loop's rate with
 * the encoders' counts and the measured winding current, and (for a cascade
 * drive) loop_current_tick() at the current loop's rate; the loop's output
 * is the terminal voltage the output stage is to apply (loop_t.v; the duty
 * is v / supply). Three structures, as servoid's twins run them
 * (servoid/drivers/twin/firmware.py, of which this is the C port, operation
 * for operation, so that both give the same numbers):
 *
 *   dynamixel_position  PID on the loop encoder's counts -> PWM duty
 *   feetech_position    the same with an insensitive zone and a minimum output
 *   cascade             position P -> velocity PI -> current PI -> voltage
 *
 * Gains and limits come as the arrays of twin_layout.h (phys[] for the few
 * physical constants a drive knows: encoder resolutions, gear ratio, supply,
 * duty limit; fw[] for the firmware's settings). No dynamic memory; needs
 * <math.h> (floor, fabs, copysign). Angles are rad, at the output shaft for
 * set points, at the loop encoder's shaft inside the loop.
 */
#ifndef SERVOID_LOOP_H
#define SERVOID_LOOP_H

#include <stdint.h>

#include "twin_layout.h"

typedef struct {
    const double *phys;      /* TW_P_SIZE constants (the drive reads only a few) */
    const double *fw;        /* TW_F_SIZE settings */
    double mem[TW_M_SIZE];   /* integrators, previous error, filters, PLL */
    /* registers, refreshed at each control tick (what a host reads) */
    double cnt_m, cnt_l;     /* encoder counts as sampled */
    double vel;              /* velocity estimate, output rad/s */
    double pos_est;          /* position estimate on the loop encoder, output rad */
    double cur;              /* current measured at the tick, A */
    double duty;             /* duty commanded, -1..1 */
    double sp;               /* latched set point, output rad (clipped to the travel) */
    double pending;          /* set point waiting for the next tick, output rad */
    int has_pending;
    int64_t tick_k;          /* the timer's count at the latest control tick */
    /* output stage */
    int enabled;             /* 1 with the output stage on */
    int fault;               /* TW_FAULT_*: why the loop turned the stage off by itself */
    double v;                /* terminal voltage to apply, V */
    double i_cmd;            /* current set point of a cascade, A */
} loop_t;

/* Set up a loop on the given constants (kept by pointer); stage off. */
void loop_init(loop_t *l, const double *phys, const double *fw);
/* Power-up: memory cleared, the first tick has no previous reading. */
void loop_reset(loop_t *l);
/* Torque on: the set point becomes the present position (nothing jumps). Off: stage open. */
void loop_enable(loop_t *l, int on);
/* The host's set point, output rad: latched at the next control tick. */
void loop_command(loop_t *l, double sp);
/* One control tick: sample (counts and current as measured), latch, estimate, control. */
void loop_control_tick(loop_t *l, double cnt_m, double cnt_l, double current, int64_t k);
/* One tick of a cascade's current PI (no-op for the PID structures); current as measured. */
void loop_current_tick(loop_t *l, double current);
/* The loop encoder's reading as an output angle, rad. */
double loop_position(const loop_t *l);

#endif
