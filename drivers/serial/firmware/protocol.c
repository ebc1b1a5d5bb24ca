/* protocol.c - framing, CRC and number formatting of the servoid bench protocol. */
#include "protocol.h"

#include <string.h>

uint16_t proto_crc16(const uint8_t *data, int n)
{
    /* CRC-16/CCITT-FALSE, bitwise: 8 shifts a byte is cheap at these frame
     * sizes and needs no 512-byte table in flash. Equals Python's
     * binascii.crc_hqx(data, 0xFFFF). */
    uint16_t crc = 0xFFFFu;
    int i, bit;
    for (i = 0; i < n; i++) {
        crc ^= (uint16_t)((uint16_t)data[i] << 8);
        for (bit = 0; bit < 8; bit++) {
            crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x1021u) : (uint16_t)(crc << 1);
        }
    }
    return crc;
}

static int hex_value(uint8_t c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

int proto_check(const uint8_t *line, int n)
{
    int body = n - 5, i;
    uint16_t want = 0;
    if (body < 1 || n >= PROTO_MAX_FRAME || line[body] != '*') return -1;
    for (i = 0; i < body; i++) {
        if (line[i] < 0x20 || line[i] > 0x7E || line[i] == '*') return -1;
    }
    for (i = body + 1; i < n; i++) {
        int v = hex_value(line[i]);
        if (v < 0) return -1;
        want = (uint16_t)((want << 4) | (uint16_t)v);
    }
    return proto_crc16(line, body) == want ? body : -1;
}

int proto_finish(uint8_t *buf, int body_len)
{
    static const char digits[] = "0123456789ABCDEF";
    uint16_t crc = proto_crc16(buf, body_len);
    int pos = body_len;
    buf[pos++] = '*';
    buf[pos++] = (uint8_t)digits[(crc >> 12) & 0xF];
    buf[pos++] = (uint8_t)digits[(crc >> 8) & 0xF];
    buf[pos++] = (uint8_t)digits[(crc >> 4) & 0xF];
    buf[pos++] = (uint8_t)digits[crc & 0xF];
    buf[pos++] = '\n';
    return pos;
}

int proto_tokens(char *body, int n, char *tokens[PROTO_MAX_TOKENS])
{
    int count = 0, i, start = 0;
    for (i = 0; i <= n; i++) {
        if (i == n || body[i] == ' ') {
            if (i == start || count == PROTO_MAX_TOKENS) return -1;
            tokens[count++] = body + start;
            body[i] = '\0'; /* at i == n this overwrites the '*' after BODY */
            start = i + 1;
        }
    }
    return count;
}

int proto_parse_u32(const char *tok, uint32_t max, uint32_t *out)
{
    uint32_t v = 0;
    int digits = 0;
    for (; *tok; tok++) {
        uint32_t d;
        if (*tok < '0' || *tok > '9' || digits == 10) return -1;
        d = (uint32_t)(*tok - '0');
        if (v > (max - d) / 10u) return -1;
        v = v * 10u + d;
        digits++;
    }
    if (digits == 0) return -1;
    *out = v;
    return 0;
}

int proto_parse_i32(const char *tok, int32_t *out)
{
    uint32_t mag;
    if (*tok == '-') {
        if (proto_parse_u32(tok + 1, 2147483648u, &mag) != 0) return -1;
        *out = (mag == 2147483648u) ? INT32_MIN : -(int32_t)mag;
        return 0;
    }
    if (proto_parse_u32(tok, 2147483647u, &mag) != 0) return -1;
    *out = (int32_t)mag;
    return 0;
}

static void put_byte(uint8_t *buf, int cap, int *pos, uint8_t c)
{
    if (*pos < cap) buf[(*pos)++] = c;
}

static void separate(uint8_t *buf, int cap, int *pos)
{
    if (*pos > 0) put_byte(buf, cap, pos, ' ');
}

void proto_put_str(uint8_t *buf, int cap, int *pos, const char *s)
{
    separate(buf, cap, pos);
    while (*s) put_byte(buf, cap, pos, (uint8_t)*s++);
}

static void put_digits(uint8_t *buf, int cap, int *pos, uint32_t v)
{
    char tmp[10];
    int n = 0;
    do {
        tmp[n++] = (char)('0' + v % 10u);
        v /= 10u;
    } while (v);
    while (n) put_byte(buf, cap, pos, (uint8_t)tmp[--n]);
}

void proto_put_u32(uint8_t *buf, int cap, int *pos, uint32_t v)
{
    separate(buf, cap, pos);
    put_digits(buf, cap, pos, v);
}

void proto_put_i32(uint8_t *buf, int cap, int *pos, int32_t v)
{
    separate(buf, cap, pos);
    if (v < 0) {
        put_byte(buf, cap, pos, '-');
        put_digits(buf, cap, pos, (uint32_t)(-(v + 1)) + 1u);
    } else {
        put_digits(buf, cap, pos, (uint32_t)v);
    }
}

void proto_put_hex16(uint8_t *buf, int cap, int *pos, uint16_t v)
{
    static const char digits[] = "0123456789abcdef";
    int shift;
    separate(buf, cap, pos);
    for (shift = 12; shift >= 0; shift -= 4) put_byte(buf, cap, pos, (uint8_t)digits[(v >> shift) & 0xF]);
}
