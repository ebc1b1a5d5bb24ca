/* twin_sim.c - the twin's physics, the host build's motor (see twin_sim.h; the C port of kernel.py). */
#include "twin_sim.h"

#include <math.h>
#include <string.h>

#define TWO_PI 6.283185307179586

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
    return sqrt(-2.0 * log(u1)) * cos(TWO_PI * u2);
}

/* servoid.drivers.twin.encoder.quantise: the count whose interval is centred on the angle */
static double quantise(double theta, double cpr, double noise_counts)
{
    return floor(theta * cpr / TWO_PI + 0.5 + noise_counts);
}

/* One sub-step of a body's speed under torque (everything but friction) with a stick state (Karnopp). */
static double friction_step(double w, int *stuck, double torque, double inertia, double viscous, double coulomb,
                            double breakaway, double stribeck, double h)
{
    double sgn, level, w_new, rest;
    if (*stuck) {
        if (fabs(torque) <= breakaway) return 0.0;
        /* break-away: at zero speed the sliding friction is the break-away level */
        sgn = torque > 0.0 ? 1.0 : -1.0;
        *stuck = 0;
        return h * (torque - sgn * breakaway) / inertia;
    }
    if (w > 0.0) {
        sgn = 1.0;
    } else if (w < 0.0) {
        sgn = -1.0;
    } else if (torque > breakaway) {
        sgn = 1.0;
    } else if (torque < -breakaway) {
        sgn = -1.0;
    } else {
        *stuck = 1;
        return 0.0;
    }
    level = coulomb;
    if (stribeck > 0.0) {
        double x = w / stribeck;
        level += (breakaway - coulomb) * exp(-x * x);
    }
    w_new = w + h * (torque - viscous * w - sgn * level) / inertia;
    if (w_new * sgn > 0.0) {
        *stuck = 0;
        return w_new;
    }
    /* the speed reached zero within this sub-step: stuck there, unless the torque exceeds break-away */
    if (fabs(torque) <= breakaway) {
        *stuck = 1;
        return 0.0;
    }
    rest = 1.0 - w / (w - w_new);
    sgn = torque > 0.0 ? 1.0 : -1.0;
    *stuck = 0;
    return rest * h * (torque - sgn * breakaway) / inertia;
}

/* The loop's control tick: the encoders as sampled now (with noise), the current as measured. */
static void control_tick(twin_sim_t *t)
{
    const double *p = t->phys;
    double cnt_m = 0.0, cnt_l = 0.0, nm = 0.0, nl = 0.0;
    if (p[TW_P_NOISE_M] > 0.0 && p[TW_P_CPR_M] > 0.0) nm = gaussian(&t->rng_m);
    if (p[TW_P_NOISE_L] > 0.0 && p[TW_P_CPR_L] > 0.0) nl = gaussian(&t->rng_l);
    if (p[TW_P_CPR_M] > 0.0) cnt_m = quantise(t->th_m, p[TW_P_CPR_M], p[TW_P_NOISE_M] * nm);
    if (p[TW_P_CPR_L] > 0.0) cnt_l = quantise(t->th_l, p[TW_P_CPR_L], p[TW_P_NOISE_L] * nl);
    loop_control_tick(&t->loop, cnt_m, cnt_l, t->cur, t->k);
}

void twin_init(twin_sim_t *t, const double *phys, const double *fw, int output_load, uint64_t seed)
{
    memset(t, 0, sizeof *t);
    memcpy(t->phys, phys, sizeof t->phys);
    memcpy(t->fw, fw, sizeof t->fw);
    t->output_load = output_load;
    t->seed = seed;
    twin_reset(t);
}

void twin_reset(twin_sim_t *t)
{
    t->th_m = t->w_m = t->th_l = t->w_l = t->cur = 0.0;
    t->stuck_m = t->stuck_l = 1;
    t->k = 0;
    t->requested_s = 0.0;
    t->rng_m = t->seed * 0x9E3779B97F4A7C15ull + 1u;
    t->rng_l = t->seed * 0x9E3779B97F4A7C15ull + 2u;
    loop_init(&t->loop, t->phys, t->fw);
    control_tick(t); /* the drive samples its encoders at power-up (tick 0) */
}

void twin_set_play(twin_sim_t *t, double play_rad) { t->phys[TW_P_HALF_PLAY] = 0.5 * play_rad; }

double twin_output_cpr(const twin_sim_t *t)
{
    return t->output_load ? t->phys[TW_P_CPR_L] : t->phys[TW_P_CPR_M] * t->phys[TW_P_N];
}

double twin_output_counts(const twin_sim_t *t) { return t->output_load ? t->loop.cnt_l : t->loop.cnt_m; }

static void run(twin_sim_t *t, int64_t n_sub)
{
    const double *p = t->phys;
    double h = p[TW_P_H], j_m = p[TW_P_J_M], b_m = p[TW_P_B_M], tc_m = p[TW_P_TC_M], ts_m = p[TW_P_TS_M];
    double vs_m = p[TW_P_VS_M], kt = p[TW_P_KT], ke = p[TW_P_KE], res = p[TW_P_R], decay = p[TW_P_EL_DECAY];
    double n = p[TW_P_N], half_play = p[TW_P_HALF_PLAY], k_g = p[TW_P_K], c_g = p[TW_P_C], eta = p[TW_P_ETA];
    double j_l = p[TW_P_J_L], b_l = p[TW_P_B_L], tc_l = p[TW_P_TC_L], ts_l = p[TW_P_TS_L], vs_l = p[TW_P_VS_L];
    double mgl = p[TW_P_MGL];
    int64_t spt = (int64_t)t->fw[TW_F_SPT], spc = (int64_t)t->fw[TW_F_SPC], i;
    double volt = t->loop.v;
    int enabled = t->loop.enabled;

    for (i = 0; i < n_sub; i++) {
        double delta, torque_c = 0.0, power, reaction;
        int tick;
        /* winding current: exact for the voltage and speed held over the sub-step */
        if (enabled) {
            double i_ss = (volt - ke * t->w_m) / res;
            t->cur = i_ss + (t->cur - i_ss) * decay;
        } else {
            t->cur = 0.0;
        }
        /* gear: free inside the play, a one-sided spring and damper past a flank */
        delta = t->th_m / n - t->th_l;
        if (delta > half_play) {
            torque_c = k_g * (delta - half_play) + c_g * (t->w_m / n - t->w_l);
            if (torque_c < 0.0) torque_c = 0.0;
        } else if (delta < -half_play) {
            torque_c = k_g * (delta + half_play) + c_g * (t->w_m / n - t->w_l);
            if (torque_c > 0.0) torque_c = 0.0;
        }
        /* who drives: the power the gear passes to the load; at rest, the motor if its own torque
         * pushes the way the contact does (a passive motor is always driven) */
        power = torque_c * t->w_l;
        if (power > 0.0 || (power == 0.0 && torque_c * t->cur > 0.0)) {
            reaction = torque_c / (n * eta);
        } else {
            reaction = torque_c * eta / n;
        }
        t->w_m = friction_step(t->w_m, &t->stuck_m, kt * t->cur - reaction, j_m, b_m, tc_m, ts_m, vs_m, h);
        t->w_l = friction_step(t->w_l, &t->stuck_l, torque_c - mgl * sin(t->th_l), j_l, b_l, tc_l, ts_l, vs_l, h);
        t->th_m += h * t->w_m;
        t->th_l += h * t->w_l;
        t->k += 1;
        tick = t->k % spt == 0;
        if (tick || t->k % spc == 0) {
            if (tick) control_tick(t);
            loop_current_tick(&t->loop, t->cur);
            volt = t->loop.v;
            enabled = t->loop.enabled;
        }
    }
}

void twin_advance(twin_sim_t *t, double dt_s)
{
    int64_t n;
    t->requested_s += dt_s;
    /* rint: to nearest, ties to even, as Python's round() */
    n = (int64_t)rint(t->requested_s / t->phys[TW_P_H]) - t->k;
    if (n > 0) run(t, n);
}
