/*
 * protocol.h - framing of the servoid bench protocol (docs/serial-protocol.md).
 *
 * A frame is one line of printable ASCII: BODY '*' CRC '\n', where CRC is the
 * CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of BODY as four upper-case
 * hex digits. BODY is space-separated tokens. No dynamic memory.
 */
#ifndef SERVOID_PROTOCOL_H
#define SERVOID_PROTOCOL_H

#include <stdint.h>

#define PROTO_VERSION 1
#define PROTO_MAX_FRAME 80   /* bytes, including '*', CRC and '\n' */
#define PROTO_MAX_TOKENS 8

uint16_t proto_crc16(const uint8_t *data, int n);

/* Check a received line (without its '\n'): returns the length of BODY, or -1
 * when the line is not a well-formed frame with a matching CRC. */
int proto_check(const uint8_t *line, int n);

/* Append '*', the CRC of buf[0..body_len) and '\n'; returns the frame length. */
int proto_finish(uint8_t *buf, int body_len);

/* Split BODY (n bytes, followed by at least one writable byte, the '*') in
 * place into at most PROTO_MAX_TOKENS NUL-terminated tokens; returns the
 * count, or -1 for an empty token or too many. */
int proto_tokens(char *body, int n, char *tokens[PROTO_MAX_TOKENS]);

/* Strict decimal parsers: the whole token, in range; return 0 on success. */
int proto_parse_u32(const char *tok, uint32_t max, uint32_t *out);
int proto_parse_i32(const char *tok, int32_t *out);

/* Formatting into buf at *pos (bounded by cap); a separating space is added
 * before each field except the first of a frame. */
void proto_put_str(uint8_t *buf, int cap, int *pos, const char *s);
void proto_put_u32(uint8_t *buf, int cap, int *pos, uint32_t v);
void proto_put_i32(uint8_t *buf, int cap, int *pos, int32_t v);
void proto_put_hex16(uint8_t *buf, int cap, int *pos, uint16_t v);

#endif
