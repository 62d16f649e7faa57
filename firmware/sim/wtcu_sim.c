/*
 * wtcu-sim: hardware-in-the-loop harness for the WTCU firmware on simavr.
 *
 * See firmware/sim/README.md for the command line, the stdout line formats
 * and the simulated peripherals.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <pty.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <simavr/sim_avr.h>
#include <simavr/sim_elf.h>
#include <simavr/sim_irq.h>
#include <simavr/sim_io.h>
#include <simavr/sim_cycle_timers.h>
#include <simavr/avr_ioport.h>
#include <simavr/avr_uart.h>
#include <simavr/avr_adc.h>
#include <simavr/avr_twi.h>
#include <simavr/avr_extint.h>

#define EXIT_USAGE 2

/* ------------------------------------------------------------------ */
/* configuration                                                        */

enum { MCU_MEGA, MCU_NANO };

static int g_mcu = -1;
static uint32_t g_freq = 16000000;
static const char *g_elf;
static uint32_t g_battery_mv = 3900;
static const char *g_gps_file;
static uint32_t g_gps_baud = 9600;
static uint32_t g_link_baud = 115200;
static double g_mag[3] = { 20.0, 0.0, 45.0 };   /* µT, board frame */
static double g_accel[3] = { 0.0, 0.0, 1.0 };   /* g, board frame */
static int g_sensor = 1;
static int g_realtime = 1;
static int g_verbose;

/* ------------------------------------------------------------------ */
/* globals                                                              */

static avr_t *avr;
static FILE *out;                 /* the real stdout (fd 1 goes to stderr) */
static volatile sig_atomic_t g_stop;
static int g_need_rearm;
static int g_pins_dirty = 1;
static uint16_t g_pins_mask;

static avr_uart_t *link_uart, *gps_uart;

static int pty_master = -1, pty_slave = -1;
static char pty_name[256];

#define RING_SIZE 65536u
typedef struct ring_t {
	uint8_t buf[RING_SIZE];
	uint32_t head, tail;      /* free-running counters */
} ring_t;
static ring_t ring_in;           /* pty -> AVR */
static ring_t ring_out;          /* AVR -> pty */
static uint64_t out_dropped;

static inline uint32_t ring_len(const ring_t *r) { return r->head - r->tail; }
static inline uint32_t ring_free(const ring_t *r) { return RING_SIZE - ring_len(r); }

/* ------------------------------------------------------------------ */
/* helpers                                                              */

static uint64_t sim_us(void)
{
	return (uint64_t)((unsigned __int128)avr->cycle * 1000000u / g_freq);
}

static uint64_t wall_us(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static void emit(const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	vfprintf(out, fmt, ap);
	va_end(ap);
	fflush(out);
}

static void die(int code, const char *fmt, ...)
{
	va_list ap;
	fprintf(stderr, "wtcu-sim: ");
	va_start(ap, fmt);
	vfprintf(stderr, fmt, ap);
	va_end(ap);
	fputc('\n', stderr);
	exit(code);
}

static void sim_logger(avr_t *a, const int level, const char *fmt, va_list ap)
{
	int lim = g_verbose ? LOG_TRACE : LOG_WARNING;
	(void)a;
	if (level > lim)
		return;
	fprintf(stderr, "simavr: ");
	vfprintf(stderr, fmt, ap);
}

static void sleep_noop(avr_t *a, avr_cycle_count_t how_long)
{
	(void)a;
	(void)how_long;	/* pacing is done by the main loop */
}

/* bytes waiting in a simavr UART receive FIFO (the header only declares it) */
static unsigned uart_rx_pending(const avr_uart_t *u)
{
	return ((unsigned)u->input.write + uart_fifo_fifo_size - u->input.read) & (uart_fifo_fifo_size - 1);
}

static avr_uart_t *find_uart(char name)
{
	for (avr_io_t *io = avr->io_port; io; io = io->next)
		if (io->kind && !strcmp(io->kind, "uart") && ((avr_uart_t *)io)->name == name)
			return (avr_uart_t *)io;
	return NULL;
}

/*
 * simavr 1.6 times a received byte as start + data + parity + stop bits,
 * counting a parity bit even when parity is off (11 bit times for 8N1
 * instead of 10). Its receiver then raises RXC only every 11 bit times,
 * ~9% slower than a line streaming back to back at the real rate: its
 * FIFO filled up and the harness silently lost about one GPS byte in 11.
 * Give the model the byte time of the frame format actually configured.
 */
static void uart_fix_byte_time(avr_uart_t *u)
{
	uint32_t ubrr = avr_regbit_get(avr, u->ubrrl) | (avr_regbit_get(avr, u->ubrrh) << 8);
	static const int databits[] = { 5, 6, 7, 8, 8, 8, 8, 9 };
	int db = databits[avr_regbit_get(avr, u->ucsz) | (avr_regbit_get(avr, u->ucsz2) << 2)];
	int parity = u->r_ucsrc && (avr->data[u->r_ucsrc] & 0x20) ? 1 : 0;	/* UPMn1 */
	int bits = 1 + db + parity + 1 + avr_regbit_get(avr, u->usbs);
	avr_cycle_count_t per_bit = (avr_cycle_count_t)(ubrr + 1) * (avr_regbit_get(avr, u->u2x) ? 8 : 16);
	u->cycles_per_byte = per_bit * (avr_cycle_count_t)bits;
}

/* ------------------------------------------------------------------ */
/* tactor pins                                                          */

static void pins_notify(avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq; (void)value; (void)param;
	g_pins_dirty = 1;
}

/* data-space addresses of PORTx / DDRx */
#define PORTA_ 0x22
#define DDRA_ 0x21
#define PORTB_ 0x25
#define DDRB_ 0x24
#define PORTC_ 0x28
#define DDRC_ 0x27
#define PORTD_ 0x2B
#define DDRD_ 0x2A

static uint8_t outhi(uint16_t port, uint16_t ddr)
{
	return avr->data[port] & avr->data[ddr];
}

static uint16_t pins_compute(void)
{
	if (g_mcu == MCU_MEGA)
		return (uint16_t)(outhi(PORTA_, DDRA_) | (outhi(PORTC_, DDRC_) << 8));
	uint16_t d = (outhi(PORTD_, DDRD_) >> 2) & 0x3F;
	uint16_t b = outhi(PORTB_, DDRB_) & 0x3F;
	uint16_t c = outhi(PORTC_, DDRC_) & 0x0F;
	return (uint16_t)(d | (b << 6) | (c << 12));
}

/*
 * A change is reported once the mask has been stable for PINS_SETTLE_US of
 * simulated time, stamped with the instant it took its final value: firmware
 * that writes PORTA then PORTC back to back gives one line, not two.
 */
#define PINS_SETTLE_US 2
static uint16_t g_pins_emitted;
static int g_pins_pending;
static uint64_t g_pins_t;
static avr_cycle_count_t g_pins_cycle;

static void pins_check(void)
{
	g_pins_dirty = 0;
	uint16_t m = pins_compute();
	if (m != g_pins_mask) {
		g_pins_mask = m;
		g_pins_t = sim_us();
		g_pins_cycle = avr->cycle;
		g_pins_pending = 1;
	}
}

static void pins_flush(int force)
{
	if (!force && avr->cycle < g_pins_cycle + (avr_cycle_count_t)g_freq / 1000000u * PINS_SETTLE_US)
		return;
	g_pins_pending = 0;
	if (g_pins_mask != g_pins_emitted) {
		g_pins_emitted = g_pins_mask;
		emit("pins %llu %04x\n", (unsigned long long)g_pins_t, g_pins_mask);
	}
}

static void pins_attach(char port)
{
	static const int irqs[] = { IOPORT_IRQ_PIN_ALL, IOPORT_IRQ_DIRECTION_ALL, IOPORT_IRQ_REG_PORT };
	for (unsigned i = 0; i < sizeof irqs / sizeof irqs[0]; i++) {
		avr_irq_t *irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(port), irqs[i]);
		if (irq)
			avr_irq_register_notify(irq, pins_notify, NULL);
	}
	for (int i = 0; i < 8; i++) {
		avr_irq_t *irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(port), IOPORT_IRQ_PIN0 + i);
		if (irq)
			avr_irq_register_notify(irq, pins_notify, NULL);
	}
}

/* ------------------------------------------------------------------ */
/* link UART <-> pty                                                    */

static void link_tx_notify(avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq; (void)param;
	uint8_t b = (uint8_t)value;
	if (b == 0)
		emit("tx %llu\n", (unsigned long long)sim_us());
	if (ring_free(&ring_out) == 0) {
		ring_out.tail++;           /* drop the oldest, nobody reads */
		if (out_dropped++ == 0)
			fprintf(stderr, "wtcu-sim: warning: pty output not read, dropping old bytes\n");
	}
	ring_out.buf[ring_out.head++ % RING_SIZE] = b;
}

/* tick at the wire's byte rate (10 bits per byte) on the simulated clock */
static avr_cycle_count_t link_base;
static uint64_t link_ticks;

static avr_cycle_count_t link_byte_at(uint64_t k)
{
	return link_base + (avr_cycle_count_t)((unsigned __int128)k * g_freq * 10 / g_link_baud);
}

static avr_cycle_count_t link_timer(avr_t *a, avr_cycle_count_t when, void *param)
{
	(void)a; (void)param;
	if (ring_len(&ring_in) && link_uart && avr_regbit_get(avr, link_uart->rxen) &&
	    uart_rx_pending(link_uart) < 2) {
		uint8_t b = ring_in.buf[ring_in.tail++ % RING_SIZE];
		if (b == 0)
			emit("rx %llu\n", (unsigned long long)sim_us());
		avr_raise_irq(link_uart->io.irq + UART_IRQ_INPUT, b);
	}
	avr_cycle_count_t next;
	do
		next = link_byte_at(++link_ticks);
	while (next <= when);
	return next;
}

static void pty_open(void)
{
	struct termios t;
	if (openpty(&pty_master, &pty_slave, pty_name, NULL, NULL) < 0)
		die(1, "openpty: %s", strerror(errno));
	if (tcgetattr(pty_slave, &t) == 0) {
		cfmakeraw(&t);
		cfsetispeed(&t, B115200);
		cfsetospeed(&t, B115200);
		tcsetattr(pty_slave, TCSANOW, &t);
	}
	fcntl(pty_master, F_SETFL, fcntl(pty_master, F_GETFL) | O_NONBLOCK);
	fcntl(pty_master, F_SETFD, FD_CLOEXEC);
	fcntl(pty_slave, F_SETFD, FD_CLOEXEC);
	/* pty_slave stays open so the master never sees a hangup when the
	 * peer closes and reopens the port. */
}

static void pty_service_read(void)
{
	while (ring_free(&ring_in)) {
		uint8_t tmp[4096];
		uint32_t n = ring_free(&ring_in);
		if (n > sizeof tmp)
			n = sizeof tmp;
		ssize_t r = read(pty_master, tmp, n);
		if (r <= 0)
			break;
		for (ssize_t i = 0; i < r; i++)
			ring_in.buf[ring_in.head++ % RING_SIZE] = tmp[i];
	}
}

static void pty_service_write(void)
{
	while (ring_len(&ring_out)) {
		uint32_t off = ring_out.tail % RING_SIZE;
		uint32_t n = ring_len(&ring_out);
		if (n > RING_SIZE - off)
			n = RING_SIZE - off;
		ssize_t w = write(pty_master, ring_out.buf + off, n);
		if (w <= 0)
			break;
		ring_out.tail += (uint32_t)w;
	}
}

/* ------------------------------------------------------------------ */
/* GPS on USART2 (mega)                                                 */

static FILE *gps_fp;
static avr_cycle_count_t gps_base;
static uint64_t gps_ticks;
static uint64_t gps_injected;     /* bytes the receiver took */
static uint64_t gps_overruns;     /* bytes lost to a receiver overrun (total) */
static uint64_t gps_overruns_warned;
static uint64_t gps_warn_wall;

/*
 * Like a real USART: a 2-byte receive buffer, and a byte arriving when both
 * are unread is lost with DOR set (valid until UDR is read). In simavr a
 * byte waits one byte time in the FIFO before RXC is raised (it plays the
 * shift register), so the receiver is full with 3 bytes pending. simavr
 * itself also refuses input while DOR is set. A lost byte is never silent:
 * DOR tells the firmware, and stderr says it (one line a second at most,
 * with a count; every one with --verbose).
 */
#define GPS_RX_DEPTH 3u

static avr_cycle_count_t gps_timer(avr_t *a, avr_cycle_count_t when, void *param)
{
	(void)a; (void)param;
	int c = fgetc(gps_fp);
	if (c == EOF) {
		rewind(gps_fp);
		c = fgetc(gps_fp);
	}
	if (c != EOF && gps_uart && avr_regbit_get(avr, gps_uart->rxen)) {
		/* like a real line: no flow control; a full receiver loses the byte */
		uart_fix_byte_time(gps_uart);
		unsigned pending = uart_rx_pending(gps_uart);
		int dor = avr_regbit_get(avr, gps_uart->dor);
		if (pending >= GPS_RX_DEPTH || (dor && pending)) {
			gps_overruns++;
			avr_regbit_setto(avr, gps_uart->dor, 1);
			if (g_verbose)
				fprintf(stderr, "wtcu-sim: GPS UART overrun at %llu us: byte 0x%02x lost, %u pending, "
					"RXC %d RXCIE %d I %d (lost %llu of %llu)\n", (unsigned long long)sim_us(), c,
					pending, avr_regbit_get(avr, gps_uart->rxc.raised),
					avr_regbit_get(avr, gps_uart->rxc.enable), avr->sreg[S_I],
					(unsigned long long)gps_overruns,
					(unsigned long long)(gps_overruns + gps_injected));
		} else {
			gps_injected++;
			avr_raise_irq(gps_uart->io.irq + UART_IRQ_INPUT, (uint8_t)c);
		}
	}
	avr_cycle_count_t next;
	do
		next = gps_base + (avr_cycle_count_t)((unsigned __int128)(++gps_ticks) * g_freq * 10 / g_gps_baud);
	while (next <= when);
	return next;
}

/* from the main loop: at most one line a second */
static void gps_warn(int force)
{
	if (gps_overruns == gps_overruns_warned)
		return;
	uint64_t w = wall_us();
	if (!force && w - gps_warn_wall < 1000000)
		return;
	gps_warn_wall = w;
	fprintf(stderr, "wtcu-sim: warning: GPS UART overrun: %llu byte(s) lost (total %llu lost, %llu received)\n",
		(unsigned long long)(gps_overruns - gps_overruns_warned), (unsigned long long)gps_overruns,
		(unsigned long long)gps_injected);
	gps_overruns_warned = gps_overruns;
}

/* ------------------------------------------------------------------ */
/* battery ADC                                                          */

static int adc_channel(void) { return g_mcu == MCU_MEGA ? ADC_IRQ_ADC0 : ADC_IRQ_ADC4; }

static void adc_set(void)
{
	avr_irq_t *irq = avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, adc_channel());
	if (irq)
		avr_raise_irq(irq, g_battery_mv / 2);
}

static void adc_trigger_notify(avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq; (void)value; (void)param;
	adc_set();	/* refresh the pin voltage at every conversion start */
}

/* ------------------------------------------------------------------ */
/* virtual LSM303AGR on TWI                                             */

#define ACC_ADDR 0x19
#define MAG_ADDR 0x1E

typedef struct sensor_t {
	uint8_t acc_regs[128];
	uint8_t mag_regs[128];
	uint8_t sel;         /* selected 7-bit address, 0 = none */
	uint8_t sel8;        /* address byte as sent (with R/W bit) */
	uint8_t reg;         /* register pointer */
	uint8_t autoinc;     /* accelerometer: bit 7 of the sub-address */
	uint8_t have_reg;    /* register pointer written in this write transfer */
} sensor_t;
static sensor_t sens;
static int g_sensor_on;
static avr_irq_t *twi_in;

/*
 * simavr 1.6 reports an acknowledged SLA+W as 0x28 (MT data ACK) and a
 * NACKed one as 0x30 instead of the datasheet's 0x18 / 0x20. Firmware that
 * checks TW_MT_SLA_ACK would fail, so the harness rewrites TWSR when the
 * status for an address phase arrives.
 */
static avr_twi_t *twi_mod;
static int twi_addr_w_pending;

static void twi_status_notify(avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq; (void)param;
	uint8_t st = (uint8_t)value & 0xF8;
	if (g_verbose)
		fprintf(stderr, "twi: status %02x%s\n", st, twi_addr_w_pending ? " (after SLA+W)" : "");
	if (!twi_addr_w_pending || st == 0x08 || st == 0x10 || st == 0xF8)
		return;
	twi_addr_w_pending = 0;
	uint8_t fixed = st == 0x28 ? 0x18 : st == 0x30 ? 0x20 : st;
	if (fixed != st && twi_mod)
		avr->data[twi_mod->twsr.reg] = (uint8_t)((avr->data[twi_mod->twsr.reg] & 0x07) | fixed);
}

static int16_t clamp16(double v)
{
	double r = round(v);
	if (r > 32767) r = 32767;
	if (r < -32768) r = -32768;
	return (int16_t)r;
}

static int16_t acc_raw(int axis)
{
	/* ±2 g high-resolution: 12-bit value, 1 mg/LSB, left-justified (<< 4) */
	double mg = round(g_accel[axis] * 1000.0);
	if (mg > 2047) mg = 2047;
	if (mg < -2048) mg = -2048;
	return (int16_t)((int32_t)mg * 16);
}

static int16_t mag_raw(int axis)
{
	return clamp16(g_mag[axis] / 0.15);	/* 1.5 mG = 0.15 µT per LSB */
}

static uint8_t sensor_read_reg(uint8_t dev, uint8_t r)
{
	r &= 0x7F;
	if (dev == ACC_ADDR) {
		if (r == 0x0F) return 0x33;
		if (r == 0x27) return 0x0F;              /* STATUS_REG_A: XYZ data ready */
		if (r >= 0x28 && r <= 0x2D) {
			int16_t v = acc_raw((r - 0x28) / 2);
			return (r & 1) ? (uint8_t)((uint16_t)v >> 8) : (uint8_t)v;
		}
		return sens.acc_regs[r];
	}
	if (r == 0x4F) return 0x40;
	if (r == 0x67) return 0x0F;                  /* STATUS_REG_M: XYZ data ready */
	if (r >= 0x68 && r <= 0x6D) {
		int16_t v = mag_raw((r - 0x68) / 2);
		return (r & 1) ? (uint8_t)((uint16_t)v >> 8) : (uint8_t)v;
	}
	return sens.mag_regs[r];
}

static void sensor_write_reg(uint8_t dev, uint8_t r, uint8_t v)
{
	r &= 0x7F;
	if (dev == ACC_ADDR) {
		if (r >= 0x1E && r <= 0x3F && !(r >= 0x27 && r <= 0x2D))
			sens.acc_regs[r] = v;
	} else {
		if (r >= 0x45 && r <= 0x66)
			sens.mag_regs[r] = v;
	}
}

static void sensor_advance(void)
{
	if (sens.sel == MAG_ADDR || sens.autoinc)
		sens.reg = (uint8_t)((sens.reg + 1) & 0x7F);
}

static void twi_out_notify(avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq; (void)param;
	avr_twi_msg_irq_t v;
	v.u.v = value;
	uint8_t msg = v.u.twi.msg;
	if (g_verbose)
		fprintf(stderr, "twi: msg %02x addr %02x data %02x\n", msg, v.u.twi.addr, v.u.twi.data);

	twi_addr_w_pending = (msg & TWI_COND_START) && !(v.u.twi.addr & 1);
	if (msg & TWI_COND_STOP) {
		sens.sel = 0;
		sens.have_reg = 0;
	}
	if (msg & TWI_COND_START) {
		uint8_t a7 = v.u.twi.addr >> 1;
		sens.sel = 0;
		sens.have_reg = 0;
		if (g_sensor_on && (a7 == ACC_ADDR || a7 == MAG_ADDR)) {
			sens.sel = a7;
			sens.sel8 = v.u.twi.addr;
			avr_raise_irq(twi_in, avr_twi_irq_msg(TWI_COND_ACK, sens.sel8, 1));
		}
		/* other addresses: no ACK => the master sees a NACK */
	}
	if (!sens.sel)
		return;
	if (msg & TWI_COND_WRITE) {
		avr_raise_irq(twi_in, avr_twi_irq_msg(TWI_COND_ACK, sens.sel8, 1));
		if (!sens.have_reg) {
			sens.have_reg = 1;
			sens.reg = v.u.twi.data & 0x7F;
			sens.autoinc = (v.u.twi.data & 0x80) != 0;
		} else {
			sensor_write_reg(sens.sel, sens.reg, v.u.twi.data);
			sensor_advance();
		}
	}
	if (msg & TWI_COND_READ) {
		uint8_t d = sensor_read_reg(sens.sel, sens.reg);
		sensor_advance();
		avr_raise_irq(twi_in, avr_twi_irq_msg(TWI_COND_READ, sens.sel8, d));
	}
}

/*
 * simavr 1.6 marks the TWI vector "sticky" and never clears TWINT when the
 * firmware writes a 1 to it, so polled TWI code sees a stale TWINT (and
 * TWSR) right after starting an operation. This second TWCR write handler
 * (simavr chains handlers of one address) clears TWINT as the datasheet says.
 */
static void twi_twcr_write(avr_t *a, avr_io_addr_t addr, uint8_t v, void *param)
{
	(void)a; (void)param;
	uint8_t m = (uint8_t)(twi_mod->twi.raised.mask << twi_mod->twi.raised.bit);
	if (addr == twi_mod->twi.raised.reg && (v & m))
		avr->data[addr] &= (uint8_t)~m;
}

static void twi_fix_attach(void)
{
	for (avr_io_t *io = avr->io_port; io; io = io->next)
		if (io->kind && !strcmp(io->kind, "twi"))
			twi_mod = (avr_twi_t *)io;
	avr_irq_t *o = avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_OUTPUT);
	avr_irq_t *s = avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_STATUS);
	if (!twi_mod || !o || !s)
		return;
	avr_irq_register_notify(o, twi_out_notify, NULL);
	avr_irq_register_notify(s, twi_status_notify, NULL);
	avr_register_io_write(avr, twi_mod->twi.raised.reg, twi_twcr_write, NULL);
}

static void sensor_attach(void)
{
	memset(&sens, 0, sizeof sens);
	sens.acc_regs[0x20] = 0x07;	/* CTRL_REG1_A reset value */
	sens.mag_regs[0x60] = 0x03;	/* CFG_REG_A_M reset value (idle) */
	g_sensor_on = 1;
	twi_in = avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_INPUT);
	if (!twi_in)
		die(1, "this MCU model has no TWI");
}

/* ------------------------------------------------------------------ */
/* reset detection                                                      */

static void on_reset(avr_t *a)
{
	(void)a;
	if (g_pins_pending)
		pins_flush(1);
	emit("reset %llu\n", (unsigned long long)sim_us());
	g_need_rearm = 1;
	g_pins_dirty = 1;
}

static void arm_timers(void)
{
	/*
	 * simavr 1.6 polls a low INTn pin every cycle while its sense control is
	 * "low level" (the reset default), even with the interrupt disabled; on
	 * the 328P tactors 0/1 sit on INT0/INT1 (PD2/PD3) and that polling slows
	 * the simulation ~8x. Low-level INTn then behaves as falling-edge.
	 * (simavr re-enables it at every reset, hence here.)
	 */
	for (uint8_t i = 0; i < EXTINT_COUNT; i++)
		if (avr_extint_is_strict_lvl_trig(avr, i) > 0)
			avr_extint_set_strict_lvl_trig(avr, i, 0);
	avr_cycle_timer_cancel(avr, link_timer, NULL);
	link_base = avr->cycle;
	link_ticks = 0;
	avr_cycle_timer_register(avr, link_byte_at(1) - avr->cycle, link_timer, NULL);
	if (gps_fp) {
		avr_cycle_timer_cancel(avr, gps_timer, NULL);
		gps_base = avr->cycle;
		gps_ticks = 0;
		avr_cycle_timer_register(avr, (avr_cycle_count_t)((uint64_t)g_freq * 10 / g_gps_baud), gps_timer, NULL);
	}
	g_need_rearm = 0;
}

/* ------------------------------------------------------------------ */
/* stdin commands                                                       */

static char in_line[1024];
static size_t in_len;
static int in_discard;

static int parse3(const char *s, double v[3])
{
	char buf[256];
	snprintf(buf, sizeof buf, "%s", s);
	for (char *p = buf; *p; p++)
		if (*p == ',')
			*p = ' ';
	char *end;
	const char *p = buf;
	double t[3];
	for (int i = 0; i < 3; i++) {
		t[i] = strtod(p, &end);
		if (end == p)
			return -1;
		p = end;
	}
	while (*p == ' ' || *p == '\t' || *p == '\r')
		p++;
	if (*p)
		return -1;
	for (int i = 0; i < 3; i++)
		v[i] = t[i];
	return 0;
}

static void command(char *l)
{
	size_t n = strlen(l);
	while (n && (l[n - 1] == '\r' || l[n - 1] == ' ' || l[n - 1] == '\t'))
		l[--n] = 0;
	while (*l == ' ' || *l == '\t')
		l++;
	if (!*l)
		return;
	if (!strcmp(l, "quit")) {
		g_stop = 1;
	} else if (!strncmp(l, "battery ", 8)) {
		char *end;
		unsigned long mv = strtoul(l + 8, &end, 10);
		if (end == l + 8 || *end || mv > 20000)
			fprintf(stderr, "wtcu-sim: bad command: %s\n", l);
		else {
			g_battery_mv = (uint32_t)mv;
			adc_set();
		}
	} else if (!strncmp(l, "mag ", 4)) {
		if (parse3(l + 4, g_mag))
			fprintf(stderr, "wtcu-sim: bad command: %s\n", l);
	} else if (!strncmp(l, "accel ", 6)) {
		if (parse3(l + 6, g_accel))
			fprintf(stderr, "wtcu-sim: bad command: %s\n", l);
	} else {
		fprintf(stderr, "wtcu-sim: unknown command: %s\n", l);
	}
}

static void stdin_service(void)
{
	char tmp[512];
	ssize_t r = read(0, tmp, sizeof tmp);
	if (r == 0) {
		g_stop = 1;	/* EOF */
		return;
	}
	if (r < 0)
		return;
	for (ssize_t i = 0; i < r; i++) {
		if (tmp[i] == '\n') {
			in_line[in_len] = 0;
			if (!in_discard)
				command(in_line);
			in_len = 0;
			in_discard = 0;
		} else if (in_len + 1 < sizeof in_line) {
			in_line[in_len++] = tmp[i];
		} else {
			in_discard = 1;	/* overlong line */
		}
	}
}

/* ------------------------------------------------------------------ */
/* main loop                                                            */

static int stdin_open = 1;

/* poll the fds, waiting at most timeout_us (0 = just look) */
static void service_io(int64_t timeout_us)
{
	struct pollfd pf[2];
	int n = 0;
	pf[n].fd = pty_master;
	pf[n].events = POLLIN | (ring_len(&ring_out) ? POLLOUT : 0);
	n++;
	if (stdin_open) {
		pf[n].fd = 0;
		pf[n].events = POLLIN;
		n++;
	}
	if (ring_free(&ring_in) == 0)
		pf[0].events &= (short)~POLLIN;
	struct timespec ts = { (time_t)(timeout_us / 1000000), (long)(timeout_us % 1000000) * 1000 };
	int r = ppoll(pf, (nfds_t)n, &ts, NULL);
	if (r <= 0)
		return;
	if (pf[0].revents & POLLIN)
		pty_service_read();
	if (pf[0].revents & POLLOUT)
		pty_service_write();
	if (n > 1 && (pf[1].revents & (POLLIN | POLLHUP | POLLERR))) {
		stdin_service();
		if (g_stop)
			stdin_open = 0;
	}
}

static void on_signal(int s)
{
	(void)s;
	g_stop = 1;
}

static void usage(void)
{
	fprintf(stderr,
		"usage: wtcu-sim --mcu atmega2560|atmega328p [--freq 16000000] --elf FILE\n"
		"                [--battery-mv 3900] [--gps FILE] [--gps-baud 9600]\n"
		"                [--mag X,Y,Z] [--accel X,Y,Z] [--no-sensor] [--no-realtime]\n"
		"                [--link-baud 115200] [--verbose]\n");
	exit(EXIT_USAGE);
}

static unsigned long parse_ul(const char *opt, const char *s, unsigned long lo, unsigned long hi)
{
	char *end;
	errno = 0;
	unsigned long v = strtoul(s, &end, 10);
	if (errno || end == s || *end || v < lo || v > hi)
		die(EXIT_USAGE, "bad value for %s: '%s'", opt, s);
	return v;
}

static void check_elf(const char *path)
{
	struct stat st;
	if (stat(path, &st) < 0)
		die(EXIT_USAGE, "cannot open ELF file '%s': %s", path, strerror(errno));
	if (!S_ISREG(st.st_mode))
		die(EXIT_USAGE, "ELF file '%s' is not a regular file", path);
	FILE *f = fopen(path, "rb");
	if (!f)
		die(EXIT_USAGE, "cannot open ELF file '%s': %s", path, strerror(errno));
	unsigned char h[40];
	size_t n = fread(h, 1, sizeof h, f);
	fclose(f);
	if (n < sizeof h || memcmp(h, "\x7f" "ELF", 4) != 0)
		die(EXIT_USAGE, "'%s' is not an ELF file", path);
	if (h[4] != 1 /* ELFCLASS32 */ || h[5] != 1 /* little endian */ || (h[18] | (h[19] << 8)) != 83 /* EM_AVR */)
		die(EXIT_USAGE, "'%s' is not an AVR ELF file", path);
	unsigned arch = h[36] & 0x7F;	/* e_flags: EF_AVR_ARCH */
	unsigned want = g_mcu == MCU_MEGA ? 6 : 5;
	if (arch && arch != want)
		fprintf(stderr, "wtcu-sim: warning: '%s' is built for avr%u, the %s is avr%u\n", path, arch,
			g_mcu == MCU_MEGA ? "atmega2560" : "atmega328p", want);
}

int main(int argc, char **argv)
{
	/* keep the real stdout for our lines; anything simavr prints goes to stderr */
	int outfd = dup(1);
	if (outfd < 0 || dup2(2, 1) < 0)
		die(1, "dup stdout: %s", strerror(errno));
	out = fdopen(outfd, "w");
	if (!out)
		die(1, "fdopen: %s", strerror(errno));
	setvbuf(out, NULL, _IOLBF, 0);
	setvbuf(stdout, NULL, _IOLBF, 0);

	for (int i = 1; i < argc; i++) {
		const char *a = argv[i];
#define NEED() do { if (i + 1 >= argc) die(EXIT_USAGE, "%s needs a value", a); } while (0)
		if (!strcmp(a, "--mcu")) {
			NEED();
			const char *m = argv[++i];
			if (!strcmp(m, "atmega2560")) g_mcu = MCU_MEGA;
			else if (!strcmp(m, "atmega328p")) g_mcu = MCU_NANO;
			else die(EXIT_USAGE, "unsupported --mcu '%s' (atmega2560 or atmega328p)", m);
		} else if (!strcmp(a, "--freq")) {
			NEED(); g_freq = (uint32_t)parse_ul(a, argv[++i], 1000, 100000000);
		} else if (!strcmp(a, "--elf")) {
			NEED(); g_elf = argv[++i];
		} else if (!strcmp(a, "--battery-mv")) {
			NEED(); g_battery_mv = (uint32_t)parse_ul(a, argv[++i], 0, 20000);
		} else if (!strcmp(a, "--gps")) {
			NEED(); g_gps_file = argv[++i];
		} else if (!strcmp(a, "--gps-baud")) {
			NEED(); g_gps_baud = (uint32_t)parse_ul(a, argv[++i], 300, 1000000);
		} else if (!strcmp(a, "--link-baud")) {
			NEED(); g_link_baud = (uint32_t)parse_ul(a, argv[++i], 300, 2000000);
		} else if (!strcmp(a, "--mag")) {
			NEED(); if (parse3(argv[++i], g_mag)) die(EXIT_USAGE, "bad value for --mag: '%s'", argv[i]);
		} else if (!strcmp(a, "--accel")) {
			NEED(); if (parse3(argv[++i], g_accel)) die(EXIT_USAGE, "bad value for --accel: '%s'", argv[i]);
		} else if (!strcmp(a, "--no-sensor")) {
			g_sensor = 0;
		} else if (!strcmp(a, "--no-realtime")) {
			g_realtime = 0;
		} else if (!strcmp(a, "--verbose")) {
			g_verbose = 1;
		} else if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
			usage();
		} else {
			fprintf(stderr, "wtcu-sim: unknown argument '%s'\n", a);
			usage();
		}
	}
	if (g_mcu < 0 || !g_elf)
		usage();
	if (g_mcu != MCU_MEGA) {
		if (g_gps_file)
			fprintf(stderr, "wtcu-sim: warning: --gps ignored on the atmega328p\n");
		g_gps_file = NULL;
		g_sensor = 0;
	}

	avr_global_logger_set(sim_logger);

	check_elf(g_elf);
	elf_firmware_t fw;
	memset(&fw, 0, sizeof fw);
	if (elf_read_firmware(g_elf, &fw) != 0 || !fw.flash || fw.flashsize == 0)
		die(EXIT_USAGE, "cannot load ELF file '%s' (no AVR code found)", g_elf);
	const char *mcu_name = g_mcu == MCU_MEGA ? "atmega2560" : "atmega328p";
	if (fw.mmcu[0] && strcmp(fw.mmcu, mcu_name))
		fprintf(stderr, "wtcu-sim: warning: '%s' says mcu '%s', simulating %s\n", g_elf, fw.mmcu, mcu_name);

	if (g_gps_file) {
		gps_fp = fopen(g_gps_file, "rb");
		if (!gps_fp)
			die(EXIT_USAGE, "cannot open GPS file '%s': %s", g_gps_file, strerror(errno));
		int c = fgetc(gps_fp);
		if (c == EOF)
			die(EXIT_USAGE, "GPS file '%s' is empty", g_gps_file);
		rewind(gps_fp);
	}

	avr = avr_make_mcu_by_name(mcu_name);
	if (!avr)
		die(1, "simavr does not know mcu %s", mcu_name);
	avr_init(avr);
	avr->log = g_verbose ? LOG_TRACE : LOG_WARNING;
	if (fw.flashbase + fw.flashsize > (uint32_t)avr->flashend + 1)
		die(EXIT_USAGE, "ELF file '%s': %u bytes of code do not fit the %s flash", g_elf,
		    (unsigned)fw.flashsize, mcu_name);
	fw.frequency = g_freq;
	fw.vcc = fw.avcc = fw.aref = 5000;
	avr_load_firmware(avr, &fw);
	avr->frequency = g_freq;
	avr->vcc = avr->avcc = avr->aref = 5000;
	avr->sleep = sleep_noop;
	avr->reset = on_reset;

	/* UARTs: no stdio echo, no polling usleep */
	for (char n = '0'; n <= '3'; n++) {
		avr_uart_t *u = find_uart(n);
		if (u)
			u->flags = 0;
	}
	link_uart = find_uart(g_mcu == MCU_MEGA ? '1' : '0');
	if (!link_uart)
		die(1, "link UART not found in the simavr model");
	if (gps_fp) {
		gps_uart = find_uart('2');
		if (!gps_uart)
			die(1, "USART2 not found in the simavr model");
	}
	avr_irq_register_notify(link_uart->io.irq + UART_IRQ_OUTPUT, link_tx_notify, NULL);

	if (g_mcu == MCU_MEGA) {
		pins_attach('A');
		pins_attach('C');
	} else {
		pins_attach('B');
		pins_attach('C');
		pins_attach('D');
	}

	avr_irq_t *trig = avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_OUT_TRIGGER);
	if (trig)
		avr_irq_register_notify(trig, adc_trigger_notify, NULL);
	adc_set();

	if (g_sensor)
		sensor_attach();
	twi_fix_attach();

	pty_open();

	struct sigaction sa;
	memset(&sa, 0, sizeof sa);
	sa.sa_handler = on_signal;
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGTERM, &sa, NULL);
	sa.sa_handler = SIG_IGN;
	sigaction(SIGPIPE, &sa, NULL);
	fcntl(0, F_SETFL, fcntl(0, F_GETFL) | O_NONBLOCK);

	emit("pty %s\n", pty_name);

	arm_timers();

	const avr_cycle_count_t service_cycles = g_freq / 4000;      /* every 250 µs simulated */
	avr_cycle_count_t next_service = avr->cycle;
	uint64_t t0 = wall_us();
	const uint64_t t_start = t0;
	uint64_t sim0 = sim_us();
	uint64_t last_warn = 0;
	int exit_code = 0;

	while (!g_stop) {
		int st = avr_run(avr);
		if (st == cpu_Done || st == cpu_Crashed) {
			fprintf(stderr, "wtcu-sim: simulation stopped (%s) at %llu us, pc=0x%x\n",
				st == cpu_Done ? "done: sleep with interrupts off?" : "crashed",
				(unsigned long long)sim_us(), (unsigned)avr->pc);
			exit_code = 1;
			break;
		}
		if (g_pins_dirty)
			pins_check();
		if (g_pins_pending)
			pins_flush(0);
		if (g_need_rearm)
			arm_timers();
		if (avr->cycle < next_service)
			continue;
		next_service = avr->cycle + service_cycles;

		if (ring_len(&ring_out))
			pty_service_write();
		gps_warn(0);
		if (!g_realtime) {
			service_io(0);
			continue;
		}
		uint64_t s = sim_us() - sim0;
		uint64_t w = wall_us() - t0;
		if (s > w + 1000) {
			/* ahead of the wall clock: wait, but wake up for input */
			service_io((int64_t)(s - w));
		} else {
			service_io(0);
			if (w > s + 50000) {
				uint64_t lag = w - s;
				if (w - last_warn >= 1000000) {
					last_warn = w;
					fprintf(stderr, "wtcu-sim: warning: simulation %llu ms behind real time\n",
						(unsigned long long)(lag / 1000));
				}
				if (lag > 1000000) {
					/* hopelessly behind (host stalled): re-anchor instead of racing */
					fprintf(stderr, "wtcu-sim: warning: re-anchoring simulated time to wall time after a %llu ms stall\n",
						(unsigned long long)(lag / 1000));
					t0 += lag;
				}
			}
		}
	}

	if (g_pins_pending)
		pins_flush(1);
	gps_warn(1);
	if (gps_fp)
		fprintf(stderr, "wtcu-sim: GPS: %llu bytes received by USART2, %llu lost to overruns\n",
			(unsigned long long)gps_injected, (unsigned long long)gps_overruns);
	fprintf(stderr, "wtcu-sim: stopped at %llu us simulated after %llu us wall\n",
		(unsigned long long)sim_us(), (unsigned long long)(wall_us() - t_start));
	pty_service_write();
	if (pty_master >= 0)
		close(pty_master);
	if (pty_slave >= 0)
		close(pty_slave);
	if (gps_fp)
		fclose(gps_fp);
	fflush(out);
	return exit_code;
}
