/*
 * Tiny AVR test program for wtcu-sim (not the WTCU firmware).
 *
 * Link UART (USART1 on the ATmega2560, USART0 on the ATmega328P), 115200 8N1:
 *   - every received byte is echoed back unchanged;
 *   - a byte 0x01 (SOH) starts a command, the next byte selects it:
 *       'P' lo hi : set the 16 tactor outputs to mask (lo | hi << 8)
 *       'A'       : read the battery ADC channel, answer "ADC=<10-bit>\n"
 *       'I'       : I2C probe, answer "WA=xx WM=xx ST=xx A=x,y,z M=x,y,z\n"
 *                   (raw i16 values; "--" for a NACKed read)
 *       'G'       : (mega) "GPS n=<bytes received on USART2> last=<last 22>\n"
 *       'W'       : enable the watchdog (250 ms) and stop feeding it
 *     (a command's own bytes are echoed too, before its answer).
 * At boot: prints "BOOT\n", pulses tactor 0 for 10 ms (busy-wait).
 */
#include <avr/io.h>
#include <avr/interrupt.h>
#include <avr/wdt.h>
#include <util/delay.h>
#include <stdint.h>

#if defined(__AVR_ATmega2560__)
#define UDRn UDR1
#define UCSRnA UCSR1A
#define UCSRnB UCSR1B
#define UCSRnC UCSR1C
#define UBRRn UBRR1
#define RX_VECT USART1_RX_vect
#define ADC_CH 0
#else
#define UDRn UDR0
#define UCSRnA UCSR0A
#define UCSRnB UCSR0B
#define UCSRnC UCSR0C
#define UBRRn UBRR0
#define RX_VECT USART_RX_vect
#define ADC_CH 4
#endif

static volatile uint8_t rxbuf[256];
static volatile uint8_t rx_head, rx_tail;

ISR(RX_VECT)
{
	uint8_t c = UDRn;
	rxbuf[rx_head++] = c;
}

static int getb(void)
{
	if (rx_head == rx_tail)
		return -1;
	return rxbuf[rx_tail++];
}

static uint8_t waitb(void)
{
	int c;
	while ((c = getb()) < 0)
		;
	return (uint8_t)c;
}

static void putb(uint8_t c)
{
	while (!(UCSRnA & _BV(UDRE0)))
		;
	UDRn = c;
}

static void puts_(const char *s)
{
	while (*s)
		putb((uint8_t)*s++);
}

static void puthex(uint8_t v)
{
	const char *h = "0123456789abcdef";
	putb(h[v >> 4]);
	putb(h[v & 15]);
}

static void putdec(int16_t v)
{
	char b[7];
	uint8_t n = 0;
	uint16_t u;
	if (v < 0) {
		putb('-');
		u = (uint16_t)(-(int32_t)v);
	} else
		u = (uint16_t)v;
	do {
		b[n++] = (char)('0' + u % 10);
		u /= 10;
	} while (u);
	while (n)
		putb((uint8_t)b[--n]);
}

static void set_mask(uint16_t m)
{
#if defined(__AVR_ATmega2560__)
	PORTA = (uint8_t)m;
	PORTC = (uint8_t)(m >> 8);
#else
	PORTD = (uint8_t)((PORTD & 0x03) | ((m & 0x3F) << 2));
	PORTB = (uint8_t)((PORTB & 0xC0) | ((m >> 6) & 0x3F));
	PORTC = (uint8_t)((PORTC & 0xF0) | ((m >> 12) & 0x0F));
#endif
}

static uint16_t adc_read(void)
{
	ADMUX = _BV(REFS0) | ADC_CH; /* AVcc reference */
	ADCSRA = _BV(ADEN) | _BV(ADSC) | 7;
	while (ADCSRA & _BV(ADSC))
		;
	return ADC;
}

/* --- polled TWI master --- */
static uint8_t twi_wait(void)
{
	uint16_t n = 0;
	while (!(TWCR & _BV(TWINT)))
		if (++n == 0)
			return 0;
	return TWSR & 0xF8;
}
static uint8_t twi_start(uint8_t sla)
{
	TWCR = _BV(TWINT) | _BV(TWSTA) | _BV(TWEN);
	twi_wait();
	TWDR = sla;
	TWCR = _BV(TWINT) | _BV(TWEN);
	uint8_t s = twi_wait();
	return s == 0x18 || s == 0x40;
}
static void twi_stop(void)
{
	TWCR = _BV(TWINT) | _BV(TWSTO) | _BV(TWEN);
}
static uint8_t twi_write(uint8_t b)
{
	TWDR = b;
	TWCR = _BV(TWINT) | _BV(TWEN);
	return twi_wait() == 0x28;
}
static uint8_t twi_read(uint8_t ack)
{
	TWCR = _BV(TWINT) | _BV(TWEN) | (ack ? _BV(TWEA) : 0);
	twi_wait();
	return TWDR;
}
/* read n registers from 7-bit address a starting at r; 0 if NACKed */
static uint8_t i2c_read(uint8_t a, uint8_t r, uint8_t *out, uint8_t n)
{
	if (!twi_start((uint8_t)(a << 1))) {
		twi_stop();
		return 0;
	}
	twi_write(r);
	if (!twi_start((uint8_t)((a << 1) | 1))) {
		twi_stop();
		return 0;
	}
	for (uint8_t i = 0; i < n; i++)
		out[i] = twi_read(i + 1 < n);
	twi_stop();
	return 1;
}
static uint8_t i2c_write1(uint8_t a, uint8_t r, uint8_t v)
{
	uint8_t ok = twi_start((uint8_t)(a << 1)) && twi_write(r) && twi_write(v);
	twi_stop();
	return ok;
}

static void put3(const uint8_t *b)
{
	for (uint8_t i = 0; i < 3; i++) {
		if (i)
			putb(',');
		putdec((int16_t)(b[2 * i] | (b[2 * i + 1] << 8)));
	}
}

static void i2c_probe(void)
{
	uint8_t b[6];
	puts_("WA=");
	if (i2c_read(0x19, 0x0F, b, 1)) puthex(b[0]); else puts_("--");
	puts_(" WM=");
	if (i2c_read(0x1E, 0x4F, b, 1)) puthex(b[0]); else puts_("--");
	puts_(" NX=");
	if (i2c_read(0x2A, 0x00, b, 1)) puthex(b[0]); else puts_("--");
	i2c_write1(0x19, 0x20, 0x57);
	puts_(" C1=");
	if (i2c_read(0x19, 0x20, b, 1)) puthex(b[0]); else puts_("--");
	puts_(" ST=");
	if (i2c_read(0x1E, 0x67, b, 1)) puthex(b[0]); else puts_("--");
	puts_(" A=");
	if (i2c_read(0x19, 0x28 | 0x80, b, 6)) put3(b); else puts_("--");
	puts_(" M=");
	if (i2c_read(0x1E, 0x68, b, 6)) put3(b); else puts_("--");
	putb('\n');
}

#if defined(__AVR_ATmega2560__)
static char gps_last[24];
static uint16_t gps_count;
static void gps_poll(void)
{
	while (UCSR2A & _BV(RXC2)) {
		char c = (char)UDR2;
		gps_count++;
		for (uint8_t i = 0; i + 2 < (uint8_t)sizeof gps_last; i++)
			gps_last[i] = gps_last[i + 1];
		gps_last[sizeof gps_last - 2] = (c == '\r' || c == '\n') ? '|' : c;
	}
}
#else
static void gps_poll(void) {}
#endif

int main(void)
{
	MCUSR = 0;
	wdt_disable();
#if defined(__AVR_ATmega2560__)
	DDRA = 0xFF;
	DDRC = 0xFF;
#else
	DDRD |= 0xFC;
	DDRB |= 0x3F;
	DDRC |= 0x0F;
#endif
	UCSRnA = _BV(U2X0);
	UBRRn = 16; /* 115200 @ 16 MHz with U2X */
	UCSRnC = 3 << UCSZ00;
	UCSRnB = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
	TWBR = 72; /* 100 kHz */
#if defined(__AVR_ATmega2560__)
	UBRR2 = 103; /* 9600 @ 16 MHz */
	UCSR2C = 3 << UCSZ20;
	UCSR2B = _BV(RXEN2);
	for (uint8_t i = 0; i < sizeof gps_last - 1; i++)
		gps_last[i] = '.';
#endif
	sei();
	puts_("BOOT\n");
	set_mask(1);
	_delay_ms(10);
	set_mask(0);
	for (;;) {
		gps_poll();
		int c = getb();
		if (c < 0)
			continue;
		putb((uint8_t)c);
		if (c != 0x01)
			continue;
		uint8_t cmd = waitb();
		putb(cmd);
		if (cmd == 'P') {
			uint8_t lo = waitb();
			putb(lo);
			uint8_t hi = waitb();
			putb(hi);
			set_mask((uint16_t)(lo | (hi << 8)));
		} else if (cmd == 'A') {
			puts_("ADC=");
			putdec((int16_t)adc_read());
			putb('\n');
		} else if (cmd == 'I') {
			i2c_probe();
#if defined(__AVR_ATmega2560__)
		} else if (cmd == 'G') {
			puts_("GPS n=");
			putdec((int16_t)gps_count);
			puts_(" last=");
			puts_(gps_last);
			putb('\n');
#endif
		} else if (cmd == 'W') {
			puts_("WDT\n");
			wdt_enable(WDTO_250MS);
			for (;;)
				;
		}
	}
}
