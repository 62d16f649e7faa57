/* WTCU framing: CRC-16/CCITT-FALSE, COBS, packet layout (docs/wtcu-protocol.md, "Framing").
 * Hardware-independent; compiled for the AVR boards and for the host test. */
#ifndef WTCU_PROTO_H
#define WTCU_PROTO_H

#include <stdint.h>

#define WTCU_MAX_PAYLOAD 200u
/* version, type, seq, len + payload + crc */
#define WTCU_MAX_PACKET (4u + WTCU_MAX_PAYLOAD + 2u)
/* COBS adds one byte per 254 data bytes (at most 1 for a packet of <= 206 bytes) */
#define WTCU_MAX_COBS (WTCU_MAX_PACKET + 1u)
/* The spec's bound on a frame between delimiters ("more than 210 bytes without a delimiter") */
#define WTCU_MAX_WIRE_BODY 210u

uint16_t wtcu_crc16(const uint8_t *data, uint16_t len);

/* Encodes len bytes of src into dst (no delimiters); returns the encoded length (<= len + 1 + len/254). */
uint16_t wtcu_cobs_encode(const uint8_t *src, uint16_t len, uint8_t *dst);

/* Decodes in place (dst may equal src); returns the decoded length, or -1 for bad COBS. */
int16_t wtcu_cobs_decode(const uint8_t *src, uint16_t len, uint8_t *dst);

/* Builds a complete wire frame (0x00 | COBS(packet) | 0x00) into out, which must hold len + 9 bytes.
 * Returns the frame length. */
uint16_t wtcu_build_frame(uint8_t version, uint8_t type, uint8_t seq, const uint8_t *payload, uint8_t len,
                          uint8_t *out);

static inline uint16_t wtcu_le16(const uint8_t *p) { return (uint16_t)(p[0] | ((uint16_t)p[1] << 8)); }
static inline void wtcu_put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

#endif
