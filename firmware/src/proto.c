/* WTCU framing helpers: CRC, COBS, frame building. */
#include "proto.h"

uint16_t wtcu_crc16(const uint8_t *data, uint16_t len)
{
    /* CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, MSB first, no final xor. Bitwise: small flash, and
     * frames are short. */
    uint16_t crc = 0xFFFFu;
    while (len--) {
        crc ^= (uint16_t)(*data++) << 8;
        for (uint8_t bit = 0; bit < 8; bit++) {
            crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x1021u) : (uint16_t)(crc << 1);
        }
    }
    return crc;
}

uint16_t wtcu_cobs_encode(const uint8_t *src, uint16_t len, uint8_t *dst)
{
    uint16_t code_at = 0; /* where the current block's length byte goes */
    uint16_t out = 1;
    uint8_t code = 1;
    for (uint16_t i = 0; i < len; i++) {
        if (src[i] == 0) {
            dst[code_at] = code;
            code_at = out++;
            code = 1;
        } else {
            dst[out++] = src[i];
            code++;
            if (code == 0xFF) {
                dst[code_at] = code;
                code_at = out++;
                code = 1;
            }
        }
    }
    dst[code_at] = code;
    return out;
}

int16_t wtcu_cobs_decode(const uint8_t *src, uint16_t len, uint8_t *dst)
{
    uint16_t in = 0;
    uint16_t out = 0;
    while (in < len) {
        uint8_t code = src[in++];
        if (code == 0) {
            return -1;
        }
        for (uint8_t k = 1; k < code; k++) {
            if (in >= len || src[in] == 0) {
                return -1;
            }
            dst[out++] = src[in++];
        }
        /* A block shorter than 0xFF stands for a zero, except at the very end. */
        if (code != 0xFF && in < len) {
            dst[out++] = 0;
        }
    }
    return (int16_t)out;
}

uint16_t wtcu_build_frame(uint8_t version, uint8_t type, uint8_t seq, const uint8_t *payload, uint8_t len,
                          uint8_t *out)
{
    /* The packet is assembled right after the space its encoding needs, then encoded to the front:
     * COBS output never overtakes its input when the input starts at least one byte further on. */
    uint8_t *pkt = out + 3;
    pkt[0] = version;
    pkt[1] = type;
    pkt[2] = seq;
    pkt[3] = len;
    for (uint8_t i = 0; i < len; i++) {
        pkt[4 + i] = payload[i];
    }
    uint16_t crc = wtcu_crc16(pkt, (uint16_t)(4u + len));
    wtcu_put16(pkt + 4 + len, crc);
    out[0] = 0;
    uint16_t n = wtcu_cobs_encode(pkt, (uint16_t)(6u + len), out + 1);
    out[1 + n] = 0;
    return (uint16_t)(n + 2u);
}
