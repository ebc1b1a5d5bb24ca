/*
 * hal_host.h - the HAL of the host build: a pseudo-terminal for the UART, the
 * monotonic clock for micros(), sim_motor for the motor and encoder, and the
 * fault injection the tests need (bit flips, lost replies, a device that goes
 * silent, a restart).
 */
#ifndef SERVOID_HAL_HOST_H
#define SERVOID_HAL_HOST_H

#include <stdint.h>
#include <stdio.h>

#include "sim_motor.h"

typedef struct {
    int fd;                    /* master side of the pty */
    double flip_tx, flip_rx;   /* probability per byte of one flipped bit, sent / received */
    double drop;               /* probability that a reply frame is not sent */
    long mute_after;           /* send no frame after this many (-1: never mute) */
    uint32_t clock_start_us;   /* micros() at power-up (to test the u32 wrap) */
    uint16_t boot_id;          /* boot id of the first power-up; 0: from the clock */
    uint32_t counts_per_rev;   /* encoder resolution */
    uint64_t seed;
    FILE *trace;               /* every frame as sent, before corruption (NULL: none) */
} hal_host_config_t;

void hal_host_init(const hal_host_config_t *cfg, sim_motor_t *motor);
/* Power cycle: the clock restarts at 0, the motor is at rest, a new boot id. */
void hal_host_reboot(void);
long hal_host_frames_sent(void);

#endif
