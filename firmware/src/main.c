/* WTCU reference firmware: main loop and board layer (timers, software PWM, UARTs, ADC, watchdogs).
 *
 * SAFETY DESIGN (also in docs/hardware.md, "Firmware safety"):
 *  1. Tactors are off with no firmware at all: every MOSFET gate has a 10 kOhm pull-down. At any reset
 *     (power-on, brown-out, hardware watchdog) the first code run, in .init3 before the C runtime sets
 *     up memory, drives every tactor pin LOW as an output and disables the watchdog left running.
 *  2. STOP_ALL is handled the moment its frame is complete: the core publishes "nothing on" to the tick
 *     ISR, which writes the pins inside the publish call, before the ACK is queued.
 *  3. Every FIRE / PLAY is checked against the limits of docs/wtcu-protocol.md (duration, continuous
 *     run across commands, tactors at once, duty cycle, pattern size) before it changes anything.
 *  4. On-times are guaranteed by scheduled instants: the core publishes to the 1 ms tick ISR the next
 *     instant at which the driven set changes (a FIRE's end, a PATTERN's next step) and the protocol
 *     watchdog's deadline (last valid frame + 1500 ms). The ISR applies them on the tick they fall on,
 *     whatever the main loop is doing; an instant the ISR's clock has already passed when a plan is
 *     published is applied by the publish itself, so a late plan never brings back an older state.
 *  5. The AVR hardware watchdog (250 ms) is reset only by the main loop: a hung main loop resets the MCU,
 *     and the reset (1.) switches every tactor off.
 *  6. Nobody reading the link never blocks anything: replies go to a bounded queue that drops (HEADING
 *     first, then GPS_DATA, then REPORT, answers last) and the UART transmitter is interrupt-driven.
 *  Bus (TWI) and ADC accesses are bounded by timeouts or non-blocking.
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/signature.h>
#include <avr/wdt.h>
#include <util/atomic.h>

#include "board.h"
#include "core.h"

/* ---------------------------------------------------------------- reset: tactors off first */

void wtcu_early_init(void) __attribute__((naked, used, section(".init3")));
void wtcu_early_init(void)
{
    MCUSR = 0;
    wdt_disable();
    board_tactor_pins_init();
}

/* ---------------------------------------------------------------- clock, plan, PWM */

static volatile uint32_t g_ms;
static struct wtcu_plan g_plan; /* ISR-owned copy; written with interrupts off */
static volatile uint16_t g_drive;

/* Software PWM: Timer2 at 8 kHz, 32 steps per period = 250 Hz, 32 levels. A tactor of level L is on for
 * ceil(L * 32 / 255) of the 32 steps: 255 is 32/32 = steady on (Timer2 is only running while a driven
 * tactor has a level strictly between 0 and 255), 0 is off. */
#define PWM_STEPS 32u
static volatile uint16_t g_pwm_nonzero; /* level > 0 */
static volatile uint16_t g_pwm_partial; /* 0 < level < 255 */
static volatile uint16_t g_pwm_cur;     /* on in the current PWM step */
static uint16_t g_off_at[PWM_STEPS];    /* switched off at step k */
static volatile uint8_t g_phase;

static inline uint8_t reached(uint32_t now, uint32_t at) { return (int32_t)(now - at) >= 0; }

/* Interrupts off. */
static void apply_outputs(void)
{
    uint16_t drive = g_drive;
    if (drive & g_pwm_partial) {
        TIMSK2 |= (1 << OCIE2A);
    } else {
        TIMSK2 &= (uint8_t)~(1 << OCIE2A);
        g_pwm_cur = g_pwm_nonzero;
    }
    board_write_tactors(drive & g_pwm_cur);
}

ISR(TIMER1_COMPA_vect)
{
    uint32_t now = g_ms + 1u;
    g_ms = now;
    uint8_t change = 0;
    if (g_plan.has_next && reached(now, g_plan.next_at)) {
        g_drive = g_plan.next_mask;
        g_plan.has_next = 0;
        change = 1;
    }
    if (g_plan.wd_armed && reached(now, g_plan.wd_at)) {
        g_drive = 0;
        g_plan.wd_armed = 0;
        g_plan.has_next = 0;
        change = 1;
    }
    if (change) {
        apply_outputs();
    }
}

ISR(TIMER2_COMPA_vect)
{
    uint8_t ph = (uint8_t)((g_phase + 1u) & (PWM_STEPS - 1u));
    g_phase = ph;
    uint16_t cur = (ph == 0) ? g_pwm_nonzero : (uint16_t)(g_pwm_cur & ~g_off_at[ph]);
    g_pwm_cur = cur;
    board_write_tactors(g_drive & cur);
}

static uint32_t clock_ms(void)
{
    uint32_t t;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { t = g_ms; }
    return t;
}

void wtcu_hw_publish(const struct wtcu_plan *plan)
{
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        g_plan = *plan;
        g_drive = plan->on;
        /* The core computed the plan from a clock read before this tick may have passed an instant in it
         * (a frame finished just before the tick that applied a pattern step). The tick already drove that
         * instant's outputs: keep them rather than drive the older state for one millisecond. */
        uint32_t now = g_ms;
        if (g_plan.has_next && reached(now, g_plan.next_at)) {
            g_drive = g_plan.next_mask;
            g_plan.has_next = 0;
        }
        if (g_plan.wd_armed && reached(now, g_plan.wd_at)) {
            g_drive = 0;
            g_plan.wd_armed = 0;
            g_plan.has_next = 0;
        }
        apply_outputs();
    }
}

void wtcu_hw_intensity(const uint8_t level[WTCU_TACTORS])
{
    uint16_t nonzero = 0, partial = 0;
    uint16_t off_at[PWM_STEPS] = {0};
    for (uint8_t t = 0; t < WTCU_TACTORS; t++) {
        uint16_t bit = (uint16_t)(1u << t);
        uint8_t steps = (uint8_t)(((uint16_t)level[t] * PWM_STEPS + 254u) / 255u);
        if (steps) {
            nonzero |= bit;
        }
        if (steps && steps < PWM_STEPS) {
            partial |= bit;
            off_at[steps] |= bit;
        }
    }
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        for (uint8_t k = 0; k < PWM_STEPS; k++) {
            g_off_at[k] = off_at[k];
        }
        g_pwm_nonzero = nonzero;
        g_pwm_partial = partial;
        g_pwm_cur = nonzero;
        apply_outputs();
    }
}

static void timers_init(void)
{
    /* Timer1: CTC, clk/64, OCR1A 249 -> 1000 Hz tick. */
    TCCR1A = 0;
    TCCR1B = (1 << WGM12) | (1 << CS11) | (1 << CS10);
    OCR1A = 249;
    TIMSK1 = (1 << OCIE1A);
    /* Timer2: CTC, clk/8, OCR2A 249 -> 8 kHz PWM step (interrupt enabled only while needed). */
    TCCR2A = (1 << WGM21);
    TCCR2B = (1 << CS21);
    OCR2A = 249;
}

/* ---------------------------------------------------------------- console link UART */

#if defined(__AVR_ATmega2560__)
#define LINK_UBRRL UBRR1L
#define LINK_UBRRH UBRR1H
#define LINK_UCSRA UCSR1A
#define LINK_UCSRB UCSR1B
#define LINK_UCSRC UCSR1C
#define LINK_UDR UDR1
#define LINK_RX_VECT USART1_RX_vect
#define LINK_UDRE_VECT USART1_UDRE_vect
#define LINK_RX_SIZE 128u
#define LINK_TX_SIZE 256u
#else
#define LINK_UBRRL UBRR0L
#define LINK_UBRRH UBRR0H
#define LINK_UCSRA UCSR0A
#define LINK_UCSRB UCSR0B
#define LINK_UCSRC UCSR0C
#define LINK_UDR UDR0
#define LINK_RX_VECT USART_RX_vect
#define LINK_UDRE_VECT USART_UDRE_vect
#define LINK_RX_SIZE 64u
#define LINK_TX_SIZE 64u
#endif
/* Bit positions are the same for every USART of these parts. */
#define B_RXC 7
#define B_UDRE 5
#define B_FE 4
#define B_DOR 3
#define B_U2X 1
#define B_RXCIE 7
#define B_UDRIE 5
#define B_RXEN 4
#define B_TXEN 3
#define B_UCSZ1 2
#define B_UCSZ0 1

#define LINK_BAUD 115200UL

static volatile uint8_t link_rx[LINK_RX_SIZE];
static volatile uint8_t link_rx_head, link_rx_tail; /* free-running, sizes are powers of two <= 256 */
static volatile uint8_t link_rx_errors;
static volatile uint8_t link_tx[LINK_TX_SIZE];
static volatile uint8_t link_tx_head, link_tx_tail;

ISR(LINK_RX_VECT)
{
    uint8_t status = LINK_UCSRA;
    uint8_t b = LINK_UDR;
    if (status & ((1 << B_FE) | (1 << B_DOR))) {
        link_rx_errors++;
    }
    uint8_t head = link_rx_head;
    if ((uint8_t)(head - link_rx_tail) >= LINK_RX_SIZE) {
        link_rx_errors++; /* buffer full: byte dropped (the frame then fails its CRC) */
        return;
    }
    link_rx[head % LINK_RX_SIZE] = b;
    link_rx_head = (uint8_t)(head + 1u);
}

ISR(LINK_UDRE_VECT)
{
    uint8_t tail = link_tx_tail;
    if (tail == link_tx_head) {
        LINK_UCSRB &= (uint8_t)~(1 << B_UDRIE);
        return;
    }
    LINK_UDR = link_tx[tail % LINK_TX_SIZE];
    link_tx_tail = (uint8_t)(tail + 1u);
}

static uint16_t ubrr_u2x(uint32_t baud) { return (uint16_t)((F_CPU + 4u * baud) / (8u * baud) - 1u); }

static void link_init(void)
{
    uint16_t ubrr = ubrr_u2x(LINK_BAUD);
    /* U2X before the baud register: simavr derives the bit rate when UBRRnL is written. */
    LINK_UCSRA = (1 << B_U2X);
    LINK_UBRRH = (uint8_t)(ubrr >> 8);
    LINK_UBRRL = (uint8_t)ubrr;
    LINK_UCSRC = (1 << B_UCSZ1) | (1 << B_UCSZ0); /* 8N1 */
    LINK_UCSRB = (1 << B_RXEN) | (1 << B_TXEN) | (1 << B_RXCIE);
}

static uint16_t link_tx_room(void)
{
    uint8_t used;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { used = (uint8_t)(link_tx_head - link_tx_tail); }
#if LINK_TX_SIZE == 256u
    /* head == tail means empty: keep one byte free */
    return (uint16_t)(255u - used);
#else
    return (uint16_t)(LINK_TX_SIZE - used);
#endif
}

static uint8_t frame_buf[(WTCU_GPS_SLOTS ? 2u + WTCU_GPS_CHUNK : 17u) + 9u];

static void link_pump_tx(void)
{
    for (;;) {
        uint16_t n = wtcu_next_frame(frame_buf, link_tx_room());
        if (!n) {
            return;
        }
        uint8_t head = link_tx_head;
        for (uint16_t i = 0; i < n; i++) {
            link_tx[head % LINK_TX_SIZE] = frame_buf[i];
            head++;
        }
        ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
        {
            link_tx_head = head;
            LINK_UCSRB |= (1 << B_UDRIE);
        }
    }
}

/* ---------------------------------------------------------------- GPS UART (Mega: USART2) */

#if BOARD_HAS_GPS
#define GPS_RX_SIZE 256u
static volatile uint8_t gps_rx[GPS_RX_SIZE];
static volatile uint8_t gps_rx_head, gps_rx_tail;
static volatile uint16_t gps_rx_lost;

ISR(USART2_RX_vect)
{
    uint8_t status = UCSR2A;
    uint8_t b = UDR2;
    uint8_t head = gps_rx_head;
    if (status & (1 << B_DOR)) {
        if (gps_rx_lost != 0xFFFFu) {
            gps_rx_lost++;
        }
    }
    if ((uint8_t)(head + 1u) == gps_rx_tail) {
        if (gps_rx_lost != 0xFFFFu) {
            gps_rx_lost++;
        }
        return;
    }
    gps_rx[head] = b;
    gps_rx_head = (uint8_t)(head + 1u);
}

void wtcu_hw_gps_open(uint32_t baud)
{
    uint16_t ubrr = ubrr_u2x(baud);
    UCSR2B = 0;
    UCSR2A = (1 << B_U2X);
    UBRR2H = (uint8_t)(ubrr >> 8);
    UBRR2L = (uint8_t)ubrr;
    UCSR2C = (1 << B_UCSZ1) | (1 << B_UCSZ0);
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        gps_rx_tail = gps_rx_head;
        gps_rx_lost = 0;
    }
    UCSR2B = (1 << B_RXEN) | (1 << B_RXCIE);
}

void wtcu_hw_gps_close(void) { UCSR2B = 0; }

static void gps_pump(uint32_t now)
{
    uint16_t lost;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        lost = gps_rx_lost;
        gps_rx_lost = 0;
    }
    if (lost) {
        wtcu_gps_lost(lost);
    }
    while (gps_rx_tail != gps_rx_head) {
        uint8_t tail = gps_rx_tail;
        wtcu_gps_byte(gps_rx[tail], now);
        gps_rx_tail = (uint8_t)(tail + 1u);
    }
}
#else
void wtcu_hw_gps_open(uint32_t baud) { (void)baud; }
void wtcu_hw_gps_close(void) {}
#endif

/* ---------------------------------------------------------------- battery ADC */

/* Divider 10k/10k from the cell to the ADC pin, AVcc (5 V) reference: mV = adc * 2 * 5000 / 1023. The
 * reading is the mean of the last 16 conversions, sampled every 10 ms without ever waiting. */
#define ADC_AVG 16u
static uint16_t adc_sum;
static uint16_t adc_samples[ADC_AVG];
static uint8_t adc_idx;
static uint32_t adc_next;

static void adc_start(void) { ADCSRA |= (1 << ADSC); }

static void adc_init(void)
{
    ADMUX = (1 << REFS0) | (BOARD_ADC_CHANNEL & 0x07);
#if defined(__AVR_ATmega2560__)
    ADCSRB = 0;
    DIDR0 = (1 << BOARD_ADC_CHANNEL);
#else
    DIDR0 = (1 << BOARD_ADC_CHANNEL);
#endif
    ADCSRA = (1 << ADEN) | (1 << ADPS2) | (1 << ADPS1) | (1 << ADPS0); /* 125 kHz ADC clock */
    /* Fill the average once at boot (16 x ~0.1 ms). */
    for (uint8_t i = 0; i < ADC_AVG; i++) {
        adc_start();
        while (ADCSRA & (1 << ADSC)) {
        }
        adc_samples[i] = ADC;
        adc_sum = (uint16_t)(adc_sum + adc_samples[i]);
    }
    adc_start();
}

static void adc_poll(uint32_t now)
{
    if (!reached(now, adc_next) || (ADCSRA & (1 << ADSC))) {
        return;
    }
    uint16_t v = ADC;
    adc_sum = (uint16_t)(adc_sum - adc_samples[adc_idx] + v);
    adc_samples[adc_idx] = v;
    adc_idx = (uint8_t)((adc_idx + 1u) % ADC_AVG);
    adc_next = now + 10u;
    adc_start();
}

uint16_t wtcu_hw_battery_mv(void)
{
    uint32_t mean = adc_sum / ADC_AVG;
    return (uint16_t)(mean * 10000u / 1023u);
}

/* ---------------------------------------------------------------- main loop */

int main(void)
{
    board_tactor_pins_init();
    timers_init();
    link_init();
    adc_init();
    struct wtcu_features feat = {0, 0};
#if BOARD_HAS_SENSORS
    feat.heading = lsm303_init();
#endif
#if BOARD_HAS_GPS
    feat.gps = 1;
#endif
    wtcu_init(&feat, clock_ms());
    sei();
    wdt_enable(WDTO_250MS);

    uint8_t seen_errors = 0;
    for (;;) {
        wdt_reset();
        uint32_t now = clock_ms();
        /* At most one buffer's worth per pass, so the loop stays bounded. */
        for (uint8_t i = 0; i < LINK_RX_SIZE && link_rx_tail != link_rx_head; i++) {
            uint8_t tail = link_rx_tail;
            uint8_t b = link_rx[tail % LINK_RX_SIZE];
            link_rx_tail = (uint8_t)(tail + 1u);
            /* The clock is read per byte: a frame is handled at the instant it is complete, so a FIRE's
             * pins are on for (duration - 1, duration] ms however long the rest of the loop took. */
            wtcu_rx_byte(b, clock_ms());
        }
        uint8_t errors = link_rx_errors;
        if (errors != seen_errors) {
            seen_errors = errors;
            wtcu_line_error();
        }
#if BOARD_HAS_GPS
        gps_pump(now);
#endif
        wtcu_poll(now);
        adc_poll(now);
#if BOARD_HAS_SENSORS
        if (feat.heading && wtcu_heading_due(now)) {
            int16_t mag[3], acc[3];
            uint8_t ok = lsm303_read(mag, acc);
            wtcu_heading_sample(mag, acc, ok);
        }
#endif
        link_pump_tx();
    }
}
