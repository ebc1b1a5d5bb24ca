/* sim_motor.c - the twin or the backlash plant, and its sample grid (see sim_motor.h). */
#include "sim_motor.h"

#include <math.h>
#include <string.h>

const char *bl_model_check(const bl_model_t *m)
{
    if (m->na < 1 || m->na > SM_MAX_NA) return "na must lie in 1..8";
    if (m->nb < 0 || m->nb > SM_MAX_NB) return "nb must lie in 0..8";
    if (m->delay < 1 || m->delay > SM_MAX_DELAY) return "delay must lie in 1..32";
    if (!(m->m2 > 0.0) || !(m->c1 > 0.0) || !(m->c2 > 0.0)) return "m2, c1 and c2 must be > 0";
    return 0;
}

void bl_plant_init(bl_plant_t *p, const bl_model_t *m)
{
    p->m = *m;
    bl_plant_reset(p);
}

void bl_plant_reset(bl_plant_t *p)
{
    memset(p->x_hist, 0, sizeof p->x_hist);
    memset(p->u_hist, 0, sizeof p->u_hist);
    p->x = 0.0;
    p->y = 0.0;
}

static double backlash(double x, double x_prev, double y_prev, double m2, double c1, double c2)
{
    /* the direction of motion picks the line (servoid.ident.models.kernels.backlash_step) */
    if (x > x_prev) {
        if (x > y_prev + c1) return x - c1;
    } else if (x < x_prev) {
        if (x < y_prev / m2 - c2) return m2 * (x + c2);
    }
    return y_prev;
}

double bl_plant_step(bl_plant_t *p, double u)
{
    const bl_model_t *m = &p->m;
    double x = 0.0;
    int i, j, len = m->delay + m->nb;
    /* same order of operations as servoid.ident.Plant.step, so the sums round alike */
    for (i = 0; i < m->na; i++) x -= m->a[i] * p->x_hist[i];
    for (j = 0; j <= m->nb; j++) x += m->b[j] * p->u_hist[m->delay - 1 + j];
    p->y = backlash(x, p->x, p->y, m->m2, m->c1, m->c2);
    for (i = m->na - 1; i > 0; i--) p->x_hist[i] = p->x_hist[i - 1];
    p->x_hist[0] = x;
    for (j = len - 1; j > 0; j--) p->u_hist[j] = p->u_hist[j - 1];
    p->u_hist[0] = u;
    p->x = x;
    return p->y;
}

/* ---- the motor on its sample grid --------------------------------------------------- */

static double gaussian(uint64_t *state)
{
    /* xorshift64* and Box-Muller: deterministic for a given seed, no libc rand() */
    double u1, u2;
    uint64_t x;
    do {
        x = *state;
        x ^= x >> 12; x ^= x << 25; x ^= x >> 27;
        *state = x;
        u1 = (double)((x * 2685821657736338717ull) >> 11) * (1.0 / 9007199254740992.0);
    } while (u1 <= 0.0);
    x = *state;
    x ^= x >> 12; x ^= x << 25; x ^= x >> 27;
    *state = x;
    u2 = (double)((x * 2685821657736338717ull) >> 11) * (1.0 / 9007199254740992.0);
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

void sim_motor_init(sim_motor_t *s, const bl_model_t *m, double counts_per_unit, double noise_std, uint64_t seed)
{
    memset(s, 0, sizeof *s);
    bl_plant_init(&s->plant, m);
    s->counts_per_unit = counts_per_unit;
    s->noise_std = noise_std;
    s->rng = seed ? seed : 0x9E3779B97F4A7C15ull;
    sim_motor_reset(s);
}

void sim_motor_init_twin(sim_motor_t *s, const double *phys, const double *fw, int output_load, uint64_t seed)
{
    memset(s, 0, sizeof *s);
    s->is_twin = 1;
    twin_init(&s->twin, phys, fw, output_load, seed);
    s->rad_per_count = 6.283185307179586 / twin_output_cpr(&s->twin);
    s->twin_period_s = SM_DEFAULT_PERIOD_US / 1e6;
    sim_motor_reset(s);
}

void sim_motor_reset(sim_motor_t *s)
{
    if (s->is_twin) {
        twin_reset(&s->twin);
        s->y_counts = twin_output_counts(&s->twin);
    } else {
        bl_plant_reset(&s->plant);
    }
    s->enabled = 0;
    s->period_us = 0;
    s->started = 0;
    s->index = -1;
    s->held = 0.0;
}

void sim_motor_enable(sim_motor_t *s, int on)
{
    if (on && !s->enabled) s->started = 0;
    if (s->is_twin) {
        loop_enable(&s->twin.loop, on); /* on also re-arms a drive that turned itself off */
        if (!on) s->started = 0;        /* the coasting samples count from the next read */
    }
    s->enabled = on;
}

void sim_motor_period(sim_motor_t *s, uint32_t period_us)
{
    s->period_us = period_us;
    s->started = 0;
    if (s->is_twin && period_us != 0) s->twin_period_s = period_us / 1e6;
}

static void step(sim_motor_t *s, double u)
{
    if (s->is_twin) {
        /* servoid.drivers.twin.TwinPlant.step: the reading at the command's arrival, then one period */
        s->y_counts = twin_output_counts(&s->twin);
        if (s->twin.loop.enabled) loop_command(&s->twin.loop, u);
        twin_advance(&s->twin, s->twin_period_s);
    } else {
        bl_plant_step(&s->plant, u);
    }
    s->index++;
}

static void hold(sim_motor_t *s, uint32_t samples)
{
    while (samples--) step(s, s->held);
}

static hal_sample_t reading(sim_motor_t *s, uint32_t t_us)
{
    hal_sample_t out;
    double y;
    if (s->is_twin) {
        out.counts = (int32_t)s->y_counts; /* a count of the twin's output encoder, noise and all */
        out.tick = (uint32_t)s->index;
        out.t_us = t_us;
        return out;
    }
    y = s->plant.y;
    if (s->noise_std > 0.0) y += s->noise_std * gaussian(&s->rng);
    y *= s->counts_per_unit;
    /* a real encoder saturates or wraps; never let the conversion overflow */
    out.counts = y >= 2147483647.0 ? INT32_MAX : y <= -2147483648.0 ? INT32_MIN : (int32_t)lround(y);
    out.tick = (uint32_t)s->index;
    out.t_us = t_us;
    return out;
}

hal_sample_t sim_motor_command(sim_motor_t *s, int32_t counts, uint32_t periods, uint32_t now_us)
{
    double u = s->is_twin ? (double)counts * s->rad_per_count : (double)counts / s->counts_per_unit;
    if (!s->enabled) return sim_motor_read(s, now_us);
    if (s->started) {
        uint32_t n = periods;
        if (n == 0 && s->period_us != 0) {
            /* whole periods since the previous sample, nearest (a half rounds up) */
            n = (uint32_t)(((uint64_t)(uint32_t)(now_us - s->last_us) + s->period_us / 2) / s->period_us);
        }
        if (n > 1) hold(s, n - 1);
    }
    step(s, u);
    s->held = u;
    s->last_us = now_us;
    s->started = 1;
    return reading(s, now_us);
}

hal_sample_t sim_motor_read(sim_motor_t *s, uint32_t now_us)
{
    int runs = s->enabled || s->is_twin; /* a twin with its stage open coasts on */
    if (runs && s->period_us != 0 && !s->started) {
        s->started = 1; /* the loop's sample times count from the first request, command or read */
        s->last_us = now_us;
    }
    if (runs && s->period_us != 0) {
        uint32_t due = (uint32_t)(now_us - s->last_us) / s->period_us;
        hold(s, due);
        s->last_us += due * s->period_us;
        return reading(s, s->last_us);
    }
    return reading(s, now_us);
}

int sim_motor_fault(const sim_motor_t *s) { return s->is_twin ? s->twin.loop.fault : 0; }
