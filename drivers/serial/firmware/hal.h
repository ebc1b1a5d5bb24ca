/*
 * hal.h - the hardware abstraction of the servoid bench firmware.
 *
 * The firmware core (firmware.c, protocol.c, loop.c) is portable C99 with no
 * dynamic memory and no libc beyond <stdint.h>/<string.h>/<math.h>;
 * everything it needs from the board is these few functions. A board port
 * (Arduino, STM32 HAL, ...) implements them over its UART, timer, motor
 * driver and encoder, and runs the position loop (loop.h) from its control
 * timer on the encoder's counts, driving the output stage with the voltage
 * the loop asks for. The host build (host/hal_host.c) implements them over a
 * pseudo-terminal and a simulated servo (host/sim_motor.h): a physical twin
 * (host/twin_sim.c) that is the loop's timer, encoders and output stage --
 * the loop is the firmware's own -- or the pseudo-Wiener model.
 *
 * Units: positions in encoder counts (int32), time in microseconds (uint32,
 * wraps after 71.6 minutes).
 */
#ifndef SERVOID_HAL_H
#define SERVOID_HAL_H

#include <stdint.h>

/* One reading of the position loop: the sample the encoder took. */
typedef struct {
    int32_t counts;   /* measured position, encoder counts */
    uint32_t tick;    /* index of the control-loop sample it belongs to */
    uint32_t t_us;    /* device time of that sample, microseconds */
} hal_sample_t;

/* Free-running microsecond clock. */
uint32_t hal_micros(void);

/* Bytes received since the last call, at most max; 0 when none (never blocks). */
int hal_uart_read(uint8_t *buf, int max);

/* Send n bytes (one whole frame per call). */
void hal_uart_write(const uint8_t *buf, int n);

/* Switch the motor's output stage on (1) or off (0). */
void hal_motor_enable(int on);

/* Period of the position loop, microseconds; 0: one loop sample per set point. */
void hal_motor_period(uint32_t period_us);

/* Latch a position set point (counts) for the loop; return the reading of the
 * sample the set point belongs to (taken before it acts). periods is how many
 * control periods after the previous set point this one comes, as the host
 * counts them (0: unknown). A motor running in real time has no use for it;
 * the host build's simulated motor steps by it, so that its samples follow
 * the host's slots exactly (see host/sim_motor.h). */
hal_sample_t hal_motor_set(int32_t counts, uint32_t periods);

/* The latest reading of the position loop. */
hal_sample_t hal_encoder_read(void);

/* Nonzero when the output stage turned itself off (a motor driver's fault pin; in the host
 * build, the twin's loop faulted, e.g. an overspeed). Cleared by hal_motor_enable(1). */
int hal_motor_fault(void);

/* Encoder counts per output revolution. */
uint32_t hal_counts_per_rev(void);

/* A number that differs from one power-up to the next (nonzero). */
uint16_t hal_boot_id(void);

/* Report an event the firmware decided on its own (the watchdog dropped the
 * torque, the output stage faulted), for whoever watches the device: the host
 * build prints it with the time; a board may blink a LED or do nothing. */
void hal_event(const char *what);

#endif
