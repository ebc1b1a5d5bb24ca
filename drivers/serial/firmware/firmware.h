/*
 * firmware.h - the servoid bench controller: requests in, readings out.
 *
 * Call fw_init() once at power-up and fw_poll() from the main loop as often as
 * possible; a board's main() is just that (see host/main.c). All state lives
 * in one fw_state_t the caller owns: no globals, no dynamic memory.
 */
#ifndef SERVOID_FIRMWARE_H
#define SERVOID_FIRMWARE_H

#include <stdint.h>

#include "protocol.h"

#define FW_NAME "servoid-bench/1.0"
#define FW_DEFAULT_WATCHDOG_MS 500u       /* torque off after this long without a request */
#define FW_MAX_PERIOD_US 1000000u
#define FW_TRAVEL_TURNS 16L               /* set points beyond +/- 16 turns are refused */

/* Error codes of X replies. */
enum {
    FW_ERR_REQUEST = 1,   /* unknown verb or malformed arguments */
    FW_ERR_TORQUE = 2,    /* S while the torque is off */
    FW_ERR_RANGE = 3,     /* an argument out of range */
    FW_ERR_PERIOD = 4,    /* R without a control period */
    FW_ERR_SLOT = 5,      /* S for a slot at or before the previous one */
    FW_ERR_FAULT = 6      /* the output stage turned itself off: the torque is off */
};

typedef struct {
    uint16_t boot;                 /* boot id of this power-up */
    uint8_t line[PROTO_MAX_FRAME]; /* request being received */
    int len;
    int overflow;                  /* the current line is too long: drop it */
    int torque;
    uint32_t period_us;
    uint32_t watchdog_ms;
    int have_slot;                 /* last_slot holds the slot of the previous set point */
    uint32_t last_slot;
    uint32_t last_request_us;
    int streaming;
    uint32_t next_stream_us;       /* when the loop's next sample is due */
    int have_stream_tick;
    uint32_t stream_tick;          /* loop sample of the last streamed frame */
    uint16_t stream_n;
    uint32_t rx_ok, rx_bad, tx;    /* frames accepted, rejected, sent */
} fw_state_t;

void fw_init(fw_state_t *fw);
void fw_poll(fw_state_t *fw);

/* Microseconds until fw_poll() has timed work to do (streaming, watchdog), or
 * UINT32_MAX when it only waits for bytes: lets a host loop sleep. */
uint32_t fw_idle_us(const fw_state_t *fw);

#endif
