/* Board layer: pin maps and peripherals of the two supported boards (ATmega2560 "mega", ATmega328P
 * "nano"). Everything here is AVR-only; the protocol core (core.c) never touches hardware. */
#ifndef WTCU_BOARD_H
#define WTCU_BOARD_H

#include <avr/io.h>
#include <stdint.h>

#if defined(__AVR_ATmega2560__)
/* Tactors 0..7: PORTA0..7 (D22..D29); 8..15: PORTC0..7 (D37..D30). */
#define BOARD_NAME "mega"
#define BOARD_HAS_GPS 1
#define BOARD_HAS_SENSORS 1
#define BOARD_ADC_CHANNEL 0 /* A0 */
static inline __attribute__((always_inline)) void board_tactor_pins_init(void)
{
    PORTA = 0;
    PORTC = 0;
    DDRA = 0xFF;
    DDRC = 0xFF;
}
static inline void board_write_tactors(uint16_t m)
{
    PORTA = (uint8_t)m;
    PORTC = (uint8_t)(m >> 8);
}
#elif defined(__AVR_ATmega328P__)
/* Tactors 0..5: PD2..PD7 (D2..D7); 6..11: PB0..PB5 (D8..D13); 12..15: PC0..PC3 (A0..A3). */
#define BOARD_NAME "nano"
#define BOARD_HAS_GPS 0
#define BOARD_HAS_SENSORS 0
#define BOARD_ADC_CHANNEL 4 /* A4 */
static inline __attribute__((always_inline)) void board_tactor_pins_init(void)
{
    PORTD &= 0x03;
    PORTB &= 0xC0;
    PORTC &= 0xF0;
    DDRD |= 0xFC;
    DDRB |= 0x3F;
    DDRC |= 0x0F;
}
static inline void board_write_tactors(uint16_t m)
{
    PORTD = (uint8_t)((PORTD & 0x03) | (uint8_t)(m << 2));
    PORTB = (uint8_t)((PORTB & 0xC0) | (uint8_t)((m >> 6) & 0x3F));
    PORTC = (uint8_t)((PORTC & 0xF0) | (uint8_t)((m >> 12) & 0x0F));
}
#else
#error "unsupported MCU: build for atmega2560 or atmega328p"
#endif

/* Magnetometer + accelerometer (lsm303.c, Mega only). Body axes x forward, y right, z down. */
uint8_t lsm303_init(void);
uint8_t lsm303_read(int16_t mag_raw[3], int16_t accel_mg[3]);

#endif
