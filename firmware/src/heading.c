/* Heading pipeline: h = W (m - b), tilt compensation, quality (docs/heading.md). */
#include "heading.h"
#include "proto.h"

#include <math.h>

#define RAD2DEG 57.29577951308232f

void wtcu_calib_identity(struct wtcu_calib *c)
{
    for (uint8_t i = 0; i < 3; i++) {
        c->b[i] = 0.0f;
        for (uint8_t j = 0; j < 3; j++) {
            c->w[i][j] = (i == j) ? 1.0f : 0.0f;
        }
    }
    c->field = 0.0f;
}

int8_t wtcu_calib_from_wire(const uint8_t *p, struct wtcu_calib *c)
{
    int32_t w[3][3];
    for (uint8_t k = 0; k < 9; k++) {
        w[k / 3][k % 3] = (int16_t)wtcu_le16(p + 6 + 2 * k);
    }
    uint16_t field = wtcu_le16(p + 24);
    if (field == 0) {
        return -1;
    }
    for (uint8_t i = 0; i < 3; i++) {
        for (uint8_t j = 0; j < 3; j++) {
            int32_t d = w[i][j] - w[j][i];
            if (d > 4 || d < -4) {
                return -1;
            }
        }
    }
    /* Leading principal minors in Q12, Q24, Q36: all positive. */
    int64_t m1 = w[0][0];
    int64_t m2 = (int64_t)w[0][0] * w[1][1] - (int64_t)w[0][1] * w[1][0];
    int64_t m3 = (int64_t)w[0][0] * ((int64_t)w[1][1] * w[2][2] - (int64_t)w[1][2] * w[2][1]) -
                 (int64_t)w[0][1] * ((int64_t)w[1][0] * w[2][2] - (int64_t)w[1][2] * w[2][0]) +
                 (int64_t)w[0][2] * ((int64_t)w[1][0] * w[2][1] - (int64_t)w[1][1] * w[2][0]);
    if (m1 <= 0 || m2 <= 0 || m3 <= 0) {
        return -1;
    }
    for (uint8_t i = 0; i < 3; i++) {
        c->b[i] = (float)(int16_t)wtcu_le16(p + 2 * i) * 0.1f;
        for (uint8_t j = 0; j < 3; j++) {
            c->w[i][j] = (float)w[i][j] / 4096.0f;
        }
    }
    c->field = (float)field * 0.1f;
    return 0;
}

static int16_t clamp_round(float v, float limit)
{
    float r = roundf(v);
    if (r > limit) {
        r = limit;
    }
    if (r < -limit) {
        r = -limit;
    }
    return (int16_t)r;
}

uint8_t wtcu_heading_payload(const float raw_ut[3], const float accel_g[3], const struct wtcu_calib *c,
                             uint8_t out[WTCU_HEADING_PAYLOAD_LEN])
{
    float d[3];
    float h[3];
    for (uint8_t i = 0; i < 3; i++) {
        d[i] = raw_ut[i] - c->b[i];
    }
    for (uint8_t i = 0; i < 3; i++) {
        h[i] = c->w[i][0] * d[0] + c->w[i][1] * d[1] + c->w[i][2] * d[2];
    }
    /* Gravity in the body is minus the specific force the accelerometer reads. */
    float gx = -accel_g[0];
    float gy = -accel_g[1];
    float gz = -accel_g[2];
    float fnorm = sqrtf(gx * gx + gy * gy + gz * gz);
    float mnorm = sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    if (!(fnorm >= 0.3f) || !(mnorm >= 0.1f)) {
        return 0;
    }
    float roll = atan2f(gy, gz);
    float pitch = atan2f(-gx, sqrtf(gy * gy + gz * gz));
    float sr = sinf(roll);
    float cr = cosf(roll);
    float sp = sinf(pitch);
    float cp = cosf(pitch);
    float xh = h[0] * cp + (h[1] * sr + h[2] * cr) * sp;
    float yh = h[1] * cr - h[2] * sr;
    if (sqrtf(xh * xh + yh * yh) < 0.001f * mnorm) {
        return 0;
    }
    float psi = atan2f(-yh, xh) * RAD2DEG;
    if (psi < 0.0f) {
        psi += 360.0f;
    }
    int32_t hc = (int32_t)roundf(psi * 100.0f);
    hc %= 36000;
    if (hc < 0) {
        hc += 36000;
    }
    uint8_t quality = 0;
    if (c->field > 0.0f) {
        float q = 100.0f * (1.0f - 2.0f * fabsf(mnorm - c->field) / c->field);
        quality = (q > 0.0f) ? (uint8_t)roundf(q) : 0;
    }
    wtcu_put16(out, (uint16_t)hc);
    wtcu_put16(out + 2, (uint16_t)clamp_round(pitch * RAD2DEG * 100.0f, 9000.0f));
    wtcu_put16(out + 4, (uint16_t)clamp_round(roll * RAD2DEG * 100.0f, 18000.0f));
    out[6] = quality;
    for (uint8_t i = 0; i < 3; i++) {
        wtcu_put16(out + 7 + 2 * i, (uint16_t)clamp_round(raw_ut[i] * 10.0f, 32767.0f));
    }
    return 1;
}
