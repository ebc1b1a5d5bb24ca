/* loop.c - the drive's loops, one tick at a time (see loop.h; the C port of servoid/drivers/twin/firmware.py). */
#include "loop.h"

#include <math.h>
#include <string.h>

#define TWO_PI 6.283185307179586

static double clip(double x, double limit)
{
    if (x > limit) return limit;
    if (x < -limit) return -limit;
    return x;
}

void loop_init(loop_t *l, const double *phys, const double *fw)
{
    memset(l, 0, sizeof *l);
    l->phys = phys;
    l->fw = fw;
    loop_reset(l);
}

void loop_reset(loop_t *l)
{
    const double *phys = l->phys, *fw = l->fw;
    memset(l, 0, sizeof *l);
    l->phys = phys;
    l->fw = fw;
    l->mem[TW_M_FIRST] = 1.0;
}

double loop_position(const loop_t *l)
{
    const double *phys = l->phys;
    if (l->fw[TW_F_LOOP_ENC] == TW_ENC_LOAD) return l->cnt_l * TWO_PI / phys[TW_P_CPR_L];
    return l->cnt_m * TWO_PI / phys[TW_P_CPR_M] / phys[TW_P_N];
}

void loop_enable(loop_t *l, int on)
{
    if (!on) {
        l->enabled = 0;
        l->v = 0.0;
        l->i_cmd = 0.0;
        l->duty = 0.0;
        return;
    }
    if (l->enabled) return;
    l->enabled = 1;
    l->fault = TW_FAULT_NONE;
    memset(l->mem, 0, sizeof l->mem);
    l->mem[TW_M_FIRST] = 1.0;
    l->sp = loop_position(l);
    l->has_pending = 0;
}

void loop_command(loop_t *l, double sp)
{
    l->pending = sp;
    l->has_pending = 1;
}

/* Position P and velocity PI of a cascade drive: sets the current command. */
static void cascade(loop_t *l, double pos_fb, double vel, double shaft_per_output, double vsup)
{
    const double *fw = l->fw;
    double *mem = l->mem;
    double vel_limit = fw[TW_F_VEL_LIMIT], vel_cmd, v_err, free, i_cmd;
    if (fabs(vel) > fw[TW_F_OVERSPEED] * vel_limit) {
        /* ODrive: ERROR_OVERSPEED, the axis drops to idle (output stage off) */
        l->fault = TW_FAULT_OVERSPEED;
        l->enabled = 0;
        l->v = 0.0;
        l->i_cmd = 0.0;
        l->duty = 0.0;
        return;
    }
    vel_cmd = clip(fw[TW_F_POS_KV] * (l->sp * shaft_per_output - pos_fb), vel_limit);
    v_err = vel_cmd - vel;
    free = fw[TW_F_VEL_KP] * v_err + mem[TW_M_INT];
    i_cmd = clip(free, fw[TW_F_CUR_LIMIT]);
    if (i_cmd != free) {
        mem[TW_M_INT] *= fw[TW_F_INT_DECAY];
    } else {
        mem[TW_M_INT] += fw[TW_F_VEL_KI] * fw[TW_F_DT] * v_err;
    }
    l->i_cmd = i_cmd;
    mem[TW_M_SAT] = 0.0;
    l->duty = l->v / vsup;
}

void loop_control_tick(loop_t *l, double cnt_m, double cnt_l, double current, int64_t k)
{
    const double *phys = l->phys, *fw = l->fw;
    double *mem = l->mem;
    double cpr_m = phys[TW_P_CPR_M], cpr_l = phys[TW_P_CPR_L];
    double cpr, counts, shaft_per_output, dt, pos, bw, pos_fb, vel, kind, vsup;
    if (cpr_m > 0.0) l->cnt_m = cnt_m;
    if (cpr_l > 0.0) l->cnt_l = cnt_l;
    l->cur = current;
    l->tick_k = k;
    if (l->has_pending) {
        double sp = l->pending;
        if (sp < fw[TW_F_SP_MIN]) {
            sp = fw[TW_F_SP_MIN];
        } else if (sp > fw[TW_F_SP_MAX]) {
            sp = fw[TW_F_SP_MAX];
        }
        l->sp = sp;
        l->has_pending = 0;
    }

    /* the loop's measurement, on the loop encoder's own shaft */
    if (fw[TW_F_LOOP_ENC] == TW_ENC_MOTOR) {
        cpr = cpr_m;
        counts = l->cnt_m;
        shaft_per_output = phys[TW_P_N];
    } else {
        cpr = cpr_l;
        counts = l->cnt_l;
        shaft_per_output = 1.0;
    }
    dt = fw[TW_F_DT];
    pos = counts * TWO_PI / cpr;
    if (mem[TW_M_FIRST] > 0.5) {
        mem[TW_M_POS_PREV] = pos;
        mem[TW_M_VEL_F] = 0.0;
        mem[TW_M_PLL_POS] = counts;
        mem[TW_M_PLL_VEL] = 0.0;
        mem[TW_M_FIRST] = 0.0;
    }
    bw = fw[TW_F_PLL_BW];
    if (bw > 0.0) {
        /* ODrive's encoder PLL, in counts: the phase detector compares the count with the integer
         * part of the estimate; a velocity below what one tick's correction resolves is zero */
        double kp = 2.0 * bw, ki = 0.25 * kp * kp, p_est, delta, v_est;
        p_est = mem[TW_M_PLL_POS] + dt * mem[TW_M_PLL_VEL];
        delta = counts - floor(p_est);
        p_est += dt * kp * delta;
        v_est = mem[TW_M_PLL_VEL] + dt * ki * delta;
        if (fabs(v_est) < 0.5 * dt * ki) v_est = 0.0;
        mem[TW_M_PLL_POS] = p_est;
        mem[TW_M_PLL_VEL] = v_est;
        pos_fb = p_est * TWO_PI / cpr;
        vel = v_est * TWO_PI / cpr;
    } else {
        double raw = (pos - mem[TW_M_POS_PREV]) / dt, tau = fw[TW_F_VEL_TAU];
        vel = tau > 0.0 ? mem[TW_M_VEL_F] + (raw - mem[TW_M_VEL_F]) * dt / (tau + dt) : raw;
        mem[TW_M_VEL_F] = vel;
        pos_fb = pos;
    }
    mem[TW_M_POS_PREV] = pos;
    l->vel = vel / shaft_per_output;
    l->pos_est = pos_fb / shaft_per_output;

    if (!l->enabled) {
        l->duty = 0.0;
        l->v = 0.0;
        l->i_cmd = 0.0;
        return;
    }
    kind = fw[TW_F_KIND];
    vsup = phys[TW_P_VSUP];
    if (kind == TW_FW_CASCADE) {
        cascade(l, pos_fb, vel, shaft_per_output, vsup);
        return;
    }

    /* PID to PWM, in counts of the loop encoder (Dynamixel, Feetech) */
    {
        double goal = floor(l->sp * shaft_per_output * cpr / TWO_PI + 0.5);
        double err = goal - counts, limit = fw[TW_F_OUT_LIMIT], out, duty;
        if (kind == TW_FW_FEETECH && fabs(err) <= fw[TW_F_DEADBAND]) {
            out = 0.0;
        } else {
            double summed = mem[TW_M_INT] + err;
            double free = fw[TW_F_KP] * err + fw[TW_F_KI] * summed + fw[TW_F_KD] * (err - mem[TW_M_E_PREV]);
            if (kind == TW_FW_FEETECH && fabs(free) < fw[TW_F_MIN_OUT]) free = copysign(fw[TW_F_MIN_OUT], err);
            out = clip(free, limit);
            if (out == free || free * err < 0.0) mem[TW_M_INT] = summed;
        }
        mem[TW_M_E_PREV] = err;
        duty = clip(out / fw[TW_F_OUT_FULL], phys[TW_P_DUTY_MAX]);
        l->duty = duty;
        l->v = duty * vsup;
    }
}

void loop_current_tick(loop_t *l, double current)
{
    const double *fw = l->fw;
    double err, free, v;
    if (fw[TW_F_KIND] != TW_FW_CASCADE || !l->enabled) return;
    err = l->i_cmd - current;
    free = fw[TW_F_CUR_KP] * err + l->mem[TW_M_CUR_INT];
    v = clip(free, fw[TW_F_V_LIMIT]);
    if (v != free) {
        l->mem[TW_M_CUR_INT] *= fw[TW_F_INT_DECAY];
        l->mem[TW_M_SAT] = 1.0;
    } else {
        l->mem[TW_M_CUR_INT] += fw[TW_F_CUR_KI] * fw[TW_F_DT_C] * err;
    }
    l->v = v;
}
