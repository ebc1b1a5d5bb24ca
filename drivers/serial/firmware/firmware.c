/* firmware.c - request handling of the servoid bench controller (docs/serial-protocol.md). */
#include "firmware.h"

#include <string.h>

#include "hal.h"

static int elapsed(uint32_t now, uint32_t since, uint32_t span)
{
    return (uint32_t)(now - since) >= span; /* unsigned difference: correct across the u32 wrap */
}

void fw_init(fw_state_t *fw)
{
    memset(fw, 0, sizeof *fw);
    fw->boot = hal_boot_id();
    fw->watchdog_ms = FW_DEFAULT_WATCHDOG_MS;
    fw->last_request_us = hal_micros();
    hal_motor_enable(0);
    hal_motor_period(0);
}

/* ---- replies ---------------------------------------------------------------------- */

static void start_reply(uint8_t *buf, int *pos, uint32_t seq, const char *type, uint16_t boot)
{
    *pos = 0;
    proto_put_u32(buf, PROTO_MAX_FRAME - 6, pos, seq);
    proto_put_str(buf, PROTO_MAX_FRAME - 6, pos, type);
    proto_put_hex16(buf, PROTO_MAX_FRAME - 6, pos, boot);
}

static void send(fw_state_t *fw, uint8_t *buf, int body_len)
{
    hal_uart_write(buf, proto_finish(buf, body_len));
    fw->tx++;
}

static void reply_ok(fw_state_t *fw, uint32_t seq)
{
    uint8_t buf[PROTO_MAX_FRAME];
    int pos;
    start_reply(buf, &pos, seq, "K", fw->boot);
    send(fw, buf, pos);
}

static void reply_error(fw_state_t *fw, uint32_t seq, uint32_t code)
{
    uint8_t buf[PROTO_MAX_FRAME];
    int pos;
    start_reply(buf, &pos, seq, "X", fw->boot);
    proto_put_u32(buf, PROTO_MAX_FRAME - 6, &pos, code);
    send(fw, buf, pos);
}

static void reply_sample(fw_state_t *fw, uint32_t seq, const char *type, hal_sample_t s)
{
    uint8_t buf[PROTO_MAX_FRAME];
    int pos;
    start_reply(buf, &pos, seq, type, fw->boot);
    proto_put_u32(buf, PROTO_MAX_FRAME - 6, &pos, s.tick);
    proto_put_u32(buf, PROTO_MAX_FRAME - 6, &pos, s.t_us);
    proto_put_i32(buf, PROTO_MAX_FRAME - 6, &pos, s.counts);
    send(fw, buf, pos);
}

static void reply_identity(fw_state_t *fw, uint32_t seq)
{
    uint8_t buf[PROTO_MAX_FRAME];
    int pos;
    start_reply(buf, &pos, seq, "I", fw->boot);
    proto_put_u32(buf, PROTO_MAX_FRAME - 6, &pos, PROTO_VERSION);
    proto_put_u32(buf, PROTO_MAX_FRAME - 6, &pos, hal_counts_per_rev());
    proto_put_str(buf, PROTO_MAX_FRAME - 6, &pos, FW_NAME);
    send(fw, buf, pos);
}

static void reply_status(fw_state_t *fw, uint32_t seq)
{
    uint8_t buf[PROTO_MAX_FRAME];
    int pos;
    start_reply(buf, &pos, seq, "Q", fw->boot);
    proto_put_u32(buf, PROTO_MAX_FRAME - 6, &pos, (uint32_t)fw->torque);
    proto_put_u32(buf, PROTO_MAX_FRAME - 6, &pos, fw->period_us);
    proto_put_u32(buf, PROTO_MAX_FRAME - 6, &pos, fw->rx_ok);
    proto_put_u32(buf, PROTO_MAX_FRAME - 6, &pos, fw->rx_bad);
    proto_put_u32(buf, PROTO_MAX_FRAME - 6, &pos, fw->tx);
    send(fw, buf, pos);
}

/* ---- requests --------------------------------------------------------------------- */

static void set_torque(fw_state_t *fw, int on)
{
    if (on != fw->torque) fw->have_slot = 0; /* slots count afresh from the first set point */
    fw->torque = on;
    hal_motor_enable(on);
}

static void set_point(fw_state_t *fw, uint32_t seq, int32_t counts, int with_slot, uint32_t slot)
{
    uint32_t periods = 0;
    if (!fw->torque) {
        reply_error(fw, seq, FW_ERR_TORQUE);
        return;
    }
    if ((long)counts > FW_TRAVEL_TURNS * (long)hal_counts_per_rev() ||
        (long)counts < -FW_TRAVEL_TURNS * (long)hal_counts_per_rev()) {
        reply_error(fw, seq, FW_ERR_RANGE);
        return;
    }
    if (with_slot) {
        if (fw->have_slot) {
            periods = slot - fw->last_slot; /* unsigned: correct across the u32 wrap */
            if (periods == 0 || periods > 0x7FFFFFFFu) {
                reply_error(fw, seq, FW_ERR_SLOT);
                return;
            }
        }
        fw->have_slot = 1;
        fw->last_slot = slot;
    }
    {
        hal_sample_t s = hal_motor_set(counts, periods);
        if (hal_motor_fault()) {
            set_torque(fw, 0); /* the stage is off already: say so rather than report a servo that coasts */
            hal_event("motor fault: the output stage turned itself off, torque off");
            reply_error(fw, seq, FW_ERR_FAULT);
            return;
        }
        reply_sample(fw, seq, "P", s);
    }
}

static void handle(fw_state_t *fw, char *body, int n)
{
    char *tok[PROTO_MAX_TOKENS];
    int count = proto_tokens(body, n, tok);
    uint32_t seq, arg = 0;
    int32_t counts;
    char verb;

    if (count < 2 || proto_parse_u32(tok[0], 65535u, &seq) != 0 || tok[1][0] == '\0' || tok[1][1] != '\0') {
        fw->rx_bad++; /* no sequence number to answer to: drop, as a corrupted frame */
        return;
    }
    fw->rx_ok++;
    fw->last_request_us = hal_micros();
    verb = tok[1][0];
    switch (verb) {
    case 'H':
        if (count != 2) break;
        reply_identity(fw, seq);
        return;
    case 'E':
        if (count != 3 || proto_parse_u32(tok[2], 1u, &arg) != 0) break;
        set_torque(fw, (int)arg);
        reply_ok(fw, seq);
        return;
    case 'C':
        if (count != 3 || proto_parse_u32(tok[2], 0xFFFFFFFFu, &arg) != 0) break;
        if (arg > FW_MAX_PERIOD_US) {
            reply_error(fw, seq, FW_ERR_RANGE);
            return;
        }
        fw->period_us = arg;
        fw->have_slot = 0;
        hal_motor_period(arg);
        reply_ok(fw, seq);
        return;
    case 'W':
        if (count != 3 || proto_parse_u32(tok[2], 600000u, &arg) != 0) break;
        fw->watchdog_ms = arg;
        reply_ok(fw, seq);
        return;
    case 'S':
        if (count < 3 || count > 4 || proto_parse_i32(tok[2], &counts) != 0) break;
        if (count == 4 && proto_parse_u32(tok[3], 0xFFFFFFFFu, &arg) != 0) break;
        set_point(fw, seq, counts, count == 4, arg);
        return;
    case 'G':
        if (count != 2) break;
        reply_sample(fw, seq, "P", hal_encoder_read());
        return;
    case 'R':
        if (count != 3 || proto_parse_u32(tok[2], 1u, &arg) != 0) break;
        if (arg && fw->period_us == 0) {
            reply_error(fw, seq, FW_ERR_PERIOD);
            return;
        }
        fw->streaming = (int)arg;
        fw->next_stream_us = hal_micros();
        fw->have_stream_tick = 0;
        reply_ok(fw, seq);
        return;
    case 'Q':
        if (count != 2) break;
        reply_status(fw, seq);
        return;
    default:
        break;
    }
    reply_error(fw, seq, FW_ERR_REQUEST);
}

static void receive(fw_state_t *fw, uint8_t c)
{
    int body;
    if (c != '\n') {
        if (fw->len < PROTO_MAX_FRAME) {
            fw->line[fw->len++] = c;
        } else {
            fw->overflow = 1;
        }
        return;
    }
    body = fw->overflow ? -1 : proto_check(fw->line, fw->len);
    if (body < 0) {
        fw->rx_bad++;
    } else {
        handle(fw, (char *)fw->line, body);
    }
    fw->len = 0;
    fw->overflow = 0;
}

void fw_poll(fw_state_t *fw)
{
    uint8_t buf[64];
    int n, i;
    uint32_t now;

    while ((n = hal_uart_read(buf, (int)sizeof buf)) > 0) {
        for (i = 0; i < n; i++) receive(fw, buf[i]);
    }
    now = hal_micros();
    if (fw->streaming && (int32_t)(now - fw->next_stream_us) >= 0) {
        /* one frame per new sample of the position loop; after a stall only the
         * latest is sent (its tick shows the gap), never a burst */
        hal_sample_t s = hal_encoder_read();
        if (!fw->have_stream_tick || s.tick != fw->stream_tick) {
            reply_sample(fw, fw->stream_n++, "D", s);
            fw->have_stream_tick = 1;
            fw->stream_tick = s.tick;
        }
        fw->next_stream_us = s.t_us + fw->period_us;
        if ((int32_t)(fw->next_stream_us - now) <= 0) fw->next_stream_us = now + fw->period_us / 4u;
    }
    if (fw->torque && fw->watchdog_ms && elapsed(now, fw->last_request_us, fw->watchdog_ms * 1000u)) {
        set_torque(fw, 0); /* the host went silent (crashed, unplugged): never leave the motor powered */
        fw->streaming = 0;
        hal_event("watchdog: no request within the watchdog time, torque off");
    }
}

uint32_t fw_idle_us(const fw_state_t *fw)
{
    uint32_t now = hal_micros(), wait = 0xFFFFFFFFu;
    if (fw->streaming) {
        int32_t left = (int32_t)(fw->next_stream_us - now);
        wait = left > 0 ? (uint32_t)left : 0u;
    }
    if (fw->torque && fw->watchdog_ms) {
        uint32_t span = fw->watchdog_ms * 1000u, gone = now - fw->last_request_us;
        uint32_t left = gone >= span ? 0u : span - gone;
        if (left < wait) wait = left;
    }
    return wait;
}
