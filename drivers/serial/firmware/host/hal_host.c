/* hal_host.c - the HAL over a pseudo-terminal and a simulated motor (see hal_host.h). */
#define _XOPEN_SOURCE 700
#include "hal_host.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "../hal.h"

static hal_host_config_t cfg;
static sim_motor_t *motor;
static uint64_t base_us;
static uint16_t boots;
static long frames_sent;
static uint64_t fault_rng;

static uint64_t mono_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static double uniform(void)
{
    uint64_t x = fault_rng;
    x ^= x >> 12; x ^= x << 25; x ^= x >> 27;
    fault_rng = x;
    return (double)((x * 2685821657736338717ull) >> 11) * (1.0 / 9007199254740992.0);
}

static void corrupt(uint8_t *buf, int n, double p)
{
    int i;
    if (p <= 0.0) return;
    for (i = 0; i < n; i++) {
        if (uniform() < p) buf[i] ^= (uint8_t)(1u << (int)(uniform() * 8.0));
    }
}

void hal_host_init(const hal_host_config_t *c, sim_motor_t *m)
{
    cfg = *c;
    motor = m;
    fault_rng = cfg.seed * 0x9E3779B97F4A7C15ull + 1u;
    base_us = mono_us();
    boots = 0;
}

void hal_host_reboot(void)
{
    base_us = mono_us();
    cfg.clock_start_us = 0;
    sim_motor_reset(motor);
}

long hal_host_frames_sent(void) { return frames_sent; }

uint32_t hal_micros(void) { return (uint32_t)(mono_us() - base_us) + cfg.clock_start_us; }

uint16_t hal_boot_id(void)
{
    uint16_t id;
    boots++;
    if (cfg.boot_id && boots == 1) return cfg.boot_id;
    id = (uint16_t)((mono_us() * 2654435761u) >> 7) ^ (uint16_t)(boots * 40503u) ^ (uint16_t)getpid();
    return id ? id : 1u;
}

int hal_uart_read(uint8_t *buf, int max)
{
    ssize_t n = read(cfg.fd, buf, (size_t)max);
    if (n <= 0) return 0; /* EAGAIN: nothing waiting */
    corrupt(buf, (int)n, cfg.flip_rx);
    return (int)n;
}

void hal_uart_write(const uint8_t *buf, int n)
{
    uint8_t out[128];
    int done = 0, waits = 0;
    if (cfg.mute_after >= 0 && frames_sent >= cfg.mute_after) return;
    frames_sent++;
    if (cfg.trace) {
        fwrite(buf, 1, (size_t)n, cfg.trace);
        fflush(cfg.trace);
    }
    if (cfg.drop > 0.0 && uniform() < cfg.drop) return;
    if (n > (int)sizeof out) n = (int)sizeof out;
    memcpy(out, buf, (size_t)n);
    corrupt(out, n, cfg.flip_tx);
    while (done < n) {
        ssize_t w = write(cfg.fd, out + done, (size_t)(n - done));
        if (w > 0) {
            done += (int)w;
        } else if (w < 0 && errno == EAGAIN && waits++ < 10) {
            struct pollfd p = {cfg.fd, POLLOUT, 0};
            poll(&p, 1, 10); /* the host is not reading: wait a little, then drop, as a full FIFO would */
        } else {
            return;
        }
    }
}

uint32_t hal_counts_per_rev(void) { return cfg.counts_per_rev; }

void hal_event(const char *what)
{
    uint64_t now = mono_us(); /* CLOCK_MONOTONIC: the same clock a watching process reads */
    fprintf(stderr, "servoid-bench-fw: %s (monotonic %llu.%06llu s)\n", what, (unsigned long long)(now / 1000000u),
            (unsigned long long)(now % 1000000u));
    fflush(stderr);
}
void hal_motor_enable(int on)
{
    static int powered;
    if (powered && !on) hal_event("torque off"); /* however it came: a request, the watchdog, a restart */
    powered = on;
    sim_motor_enable(motor, on);
}
void hal_motor_period(uint32_t period_us) { sim_motor_period(motor, period_us); }
hal_sample_t hal_motor_set(int32_t counts, uint32_t periods)
{
    return sim_motor_command(motor, counts, periods, hal_micros());
}
hal_sample_t hal_encoder_read(void) { return sim_motor_read(motor, hal_micros()); }
int hal_motor_fault(void) { return sim_motor_fault(motor); }
