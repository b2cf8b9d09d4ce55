/*
 * hcrctl's firmware harness: one AVR chip under libsimavr, held to wall time,
 * talking to hcrctl (Python) over stdin/stdout in short text lines.
 *
 * Built on demand by hcrctl/sim/firmware/harness.py with the host's cc:
 *   cc -O2 -I/usr/include/simavr harness.c -lsimavr -o hcr-avr-harness
 *
 * Usage: hcr-avr-harness MCU CLOCK_HZ FILE   (FILE: an ELF, or a raw flash image ending in .bin)
 *
 * Python -> harness (one command a line; the chip starts at the first "g"):
 *   w PIN PORT DDR BIT TCCR SHIFT OCR  watch an output pin: data-space addresses of its PORT and DDR
 *                                      registers, its bit, and (TCCR 0 if none) the timer control
 *                                      register whose COM bits at SHIFT connect the compare register OCR
 *   i PORT BIT LEVEL                   drive an input pin (PORT a letter, LEVEL 0 or 1)
 *   a CHANNEL COUNT                    what the ADC reads on CHANNEL, 0..1023 (AVcc = 5 V)
 *   u HEX                              bytes the host sent to UART0
 *   g                                  run
 * harness -> Python:
 *   r                                  firmware loaded, waiting for "g"
 *   p PIN VALUE                        a watched pin changed: -1 input, else the PWM compare value
 *                                      while the timer drives the pin, else 0 or 255 for its level
 *   u HEX                              bytes the chip sent on UART0 (at its baud rate, in chip time)
 *   t SIM_US WALL_US SLIP_US           every 10 ms of chip time: chip time, wall time since "g", and
 *                                      wall time given up because the host could not keep up
 *   e MESSAGE                          a fatal error; the harness then exits 1
 *
 * Time: the chip runs in slices of 100 us of its own time; when it is ahead of the wall clock the
 * harness sleeps (in ppoll on stdin, so input is taken at once); when it falls more than 250 ms
 * behind, the debt is given up (counted in SLIP_US) rather than run off in a burst.
 * The harness ends on stdin EOF ("hcrctl sim" ending) and ignores SIGINT (hcrctl handles Ctrl-C).
 */
#define _GNU_SOURCE
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_io.h>
#include <sim_irq.h>
#include <avr_adc.h>
#include <avr_ioport.h>
#include <avr_uart.h>

#define MAX_WATCH 32
#define SLICES_PER_SECOND 10000 /* 100 us */
#define MAX_BEHIND_NS 250000000LL

typedef struct {
	int pin, port, ddr, bit, tccr, shift, ocr, value;
} watch_t;

static avr_t *avr;
static watch_t watches[MAX_WATCH];
static int nwatch;
static unsigned char pending[65536];
static size_t pend_head, pend_tail;
static int xoff;
static char outbuf[8192];
static size_t outlen;
static char inbuf[65536];
static size_t inlen;
static int running;
/* The protocol's stream: stdout as it was at the start (simavr itself prints on stdout). */
static FILE *proto;

static void fail(const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	fprintf(proto, "e ");
	vfprintf(proto, fmt, ap);
	fprintf(proto, "\n");
	fflush(proto);
	va_end(ap);
	exit(1);
}

static long long now_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (long long)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

/* -- UART0 ----------------------------------------------------------------------------------- */

static void feed_uart(void)
{
	avr_irq_t *in = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
	while (!xoff && pend_head != pend_tail) {
		unsigned char b = pending[pend_head];
		pend_head = (pend_head + 1) % sizeof pending;
		avr_raise_irq(in, b);
	}
}

static void on_xon(struct avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq; (void)value; (void)param;
	xoff = 0;
	feed_uart();
}

static void on_xoff(struct avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq; (void)value; (void)param;
	xoff = 1;
}

static void on_uart_out(struct avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq; (void)param;
	if (outlen + 2 < sizeof outbuf) {
		static const char hex[] = "0123456789abcdef";
		outbuf[outlen++] = hex[(value >> 4) & 0xf];
		outbuf[outlen++] = hex[value & 0xf];
	}
}

static void flush_uart_out(void)
{
	if (outlen) {
		fprintf(proto, "u %.*s\n", (int)outlen, outbuf);
		outlen = 0;
	}
}

/*
 * simavr 1.6 times every UART byte as 1 start + data + 1 parity + stop bits, parity or not
 * (avr_uart_baud_write), so an 8N1 line carried 11 bit times a byte: 874 bytes/s at 9600 baud instead
 * of a real chip's 960, and a firmware paced by its own output ran 9 % slow. Without parity (UPM0 = 0)
 * the byte time is put right here, whenever simavr has set it anew.
 */
static avr_uart_t *uart0;
static avr_cycle_count_t uart0_fixed;

static void fix_uart_timing(void)
{
	static const int databits[] = { 5, 6, 7, 8, 8, 8, 8, 9 };
	if (!uart0 || uart0->cycles_per_byte == uart0_fixed)
		return;
	if ((avr->data[uart0->r_ucsrc] >> 4) & 3)
		return; /* parity on: simavr's count is right */
	int db = databits[avr_regbit_get(avr, uart0->ucsz) | (avr_regbit_get(avr, uart0->ucsz2) << 2)];
	int word = 1 + db + 1 + 1 + avr_regbit_get(avr, uart0->usbs); /* as simavr counts it */
	uart0_fixed = uart0->cycles_per_byte * (avr_cycle_count_t)(word - 1) / (avr_cycle_count_t)word;
	uart0->cycles_per_byte = uart0_fixed;
}

static void find_uart0(void)
{
	for (avr_io_t *io = avr->io_port; io; io = io->next)
		if (io->kind && strcmp(io->kind, "uart") == 0 && ((avr_uart_t *)io)->name == '0')
			uart0 = (avr_uart_t *)io;
}

/* -- pins ------------------------------------------------------------------------------------ */

static int pin_value(const watch_t *w)
{
	uint8_t mask = (uint8_t)(1u << w->bit);
	if (!(avr->data[w->ddr] & mask))
		return -1;
	if (w->tccr && ((avr->data[w->tccr] >> w->shift) & 3))
		return avr->data[w->ocr];
	return (avr->data[w->port] & mask) ? 255 : 0;
}

static void scan_pins(void)
{
	for (int i = 0; i < nwatch; i++) {
		int v = pin_value(&watches[i]);
		if (v != watches[i].value) {
			watches[i].value = v;
			fprintf(proto, "p %d %d\n", watches[i].pin, v);
		}
	}
}

/* -- commands from hcrctl -------------------------------------------------------------------- */

static int hexval(char c)
{
	if (c >= '0' && c <= '9') return c - '0';
	if (c >= 'a' && c <= 'f') return c - 'a' + 10;
	if (c >= 'A' && c <= 'F') return c - 'A' + 10;
	return -1;
}

static void command(char *line)
{
	watch_t w;
	char port;
	int bit, level, channel, count;
	if (line[0] == 'u' && line[1] == ' ') {
		for (char *p = line + 2; hexval(p[0]) >= 0 && hexval(p[1]) >= 0; p += 2) {
			size_t next = (pend_tail + 1) % sizeof pending;
			if (next == pend_head)
				break; /* the host outran a 64 KiB queue: drop, as an overrun UART would */
			pending[pend_tail] = (unsigned char)(hexval(p[0]) << 4 | hexval(p[1]));
			pend_tail = next;
		}
		feed_uart();
	} else if (sscanf(line, "i %c %d %d", &port, &bit, &level) == 3) {
		avr_irq_t *irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(port), bit);
		if (!irq)
			fail("no port %c on this MCU", port);
		avr_raise_irq(irq, level ? 1 : 0);
	} else if (sscanf(line, "a %d %d", &channel, &count) == 2) {
		avr_irq_t *irq = avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_ADC0 + channel);
		if (!irq)
			fail("no ADC channel %d on this MCU", channel);
		/* simavr reads mV * 1023 / AVcc: the smallest mV that gives COUNT */
		avr_raise_irq(irq, (uint32_t)((count * 5000 + 1022) / 1023));
	} else if (sscanf(line, "w %d %d %d %d %d %d %d", &w.pin, &w.port, &w.ddr, &w.bit, &w.tccr, &w.shift,
			  &w.ocr) == 7) {
		if (nwatch == MAX_WATCH)
			fail("too many watched pins");
		w.value = -2; /* reported at the first scan */
		watches[nwatch++] = w;
	} else if (line[0] == 'g') {
		running = 1;
	} else if (line[0]) {
		fail("unknown command: %s", line);
	}
}

/* Read what is there on stdin, wait at most timeout_ns for it; run whole lines. */
static void take_input(long long timeout_ns)
{
	struct pollfd pfd = { .fd = 0, .events = POLLIN };
	struct timespec ts = { .tv_sec = timeout_ns / 1000000000LL, .tv_nsec = timeout_ns % 1000000000LL };
	if (ppoll(&pfd, 1, timeout_ns < 0 ? NULL : &ts, NULL) <= 0)
		return;
	ssize_t n = read(0, inbuf + inlen, sizeof inbuf - inlen - 1);
	if (n == 0)
		exit(0); /* hcrctl went away */
	if (n < 0) {
		if (errno == EINTR || errno == EAGAIN)
			return;
		exit(0);
	}
	inlen += (size_t)n;
	char *start = inbuf, *nl;
	while ((nl = memchr(start, '\n', inlen - (size_t)(start - inbuf)))) {
		*nl = 0;
		command(start);
		start = nl + 1;
	}
	inlen -= (size_t)(start - inbuf);
	memmove(inbuf, start, inlen);
	if (inlen == sizeof inbuf - 1)
		fail("command line too long");
}

/* -- the chip -------------------------------------------------------------------------------- */

static void load(const char *mcu, uint32_t clock, const char *file)
{
	elf_firmware_t f;
	memset(&f, 0, sizeof f);
	size_t len = strlen(file);
	int raw = len > 4 && strcmp(file + len - 4, ".bin") == 0;
	if (!raw && elf_read_firmware(file, &f) != 0)
		fail("cannot read the ELF file %s", file);
	avr = avr_make_mcu_by_name(mcu);
	if (!avr)
		fail("simavr has no MCU named %s", mcu);
	avr_init(avr);
	avr->frequency = clock;
	if (raw) {
		static uint8_t flash[256 * 1024];
		FILE *in = fopen(file, "rb");
		if (!in)
			fail("cannot open %s: %s", file, strerror(errno));
		size_t size = fread(flash, 1, sizeof flash, in);
		fclose(in);
		if (size > (size_t)avr->flashend + 1)
			fail("the image (%zu bytes) is larger than the flash of %s", size, mcu);
		avr_loadcode(avr, flash, (uint32_t)size, 0);
	} else {
		/* hcrctl checked the file (image.py); this keeps simavr from aborting on one that does not fit */
		if ((uint64_t)f.flashbase + f.flashsize > (uint64_t)avr->flashend + 1)
			fail("the firmware (%u bytes at 0x%x) is larger than the flash of %s", f.flashsize,
			     f.flashbase, mcu);
		f.frequency = clock;
		strncpy(f.mmcu, mcu, sizeof f.mmcu - 1);
		avr_load_firmware(avr, &f);
		avr->frequency = clock;
	}
	avr->vcc = avr->avcc = avr->aref = 5000;
	avr->log = 0;

	uint32_t flags = 0;
	avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
	flags &= ~(uint32_t)(AVR_UART_FLAG_STDIO | AVR_UART_FLAG_POLL_SLEEP);
	avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
	avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), on_uart_out, NULL);
	avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON), on_xon, NULL);
	avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF), on_xoff, NULL);
	find_uart0();
}

int main(int argc, char **argv)
{
	if (argc != 4) {
		fprintf(stderr, "usage: %s MCU CLOCK_HZ FILE\n", argv[0]);
		return 2;
	}
	signal(SIGINT, SIG_IGN);
	proto = fdopen(dup(1), "w");
	dup2(2, 1);
	signal(SIGPIPE, SIG_DFL);
	uint32_t clock = (uint32_t)strtoul(argv[2], NULL, 10);
	if (clock < 1000)
		fail("clock %s Hz is too slow", argv[2]);
	load(argv[1], clock, argv[3]);
	fprintf(proto, "r\n");
	fflush(proto);
	while (!running)
		take_input(-1);

	avr_cycle_count_t slice = clock / SLICES_PER_SECOND;
	long long start = now_ns(), slip = 0;
	unsigned long n = 0;
	scan_pins();
	for (;;) {
		avr_cycle_count_t end = avr->cycle + slice;
		while (avr->cycle < end) {
			int state = avr_run(avr);
			if (state == cpu_Done || state == cpu_Crashed)
				fail("the firmware %s at %.3f s", state == cpu_Done ? "stopped" : "crashed",
				     (double)avr->cycle / clock);
		}
		fix_uart_timing();
		scan_pins();
		flush_uart_out();
		n++;
		long long sim = (long long)((double)avr->cycle * 1e9 / clock);
		long long wall = now_ns() - start;
		if (n % 100 == 0)
			fprintf(proto, "t %lld %lld %lld\n", sim / 1000, wall / 1000, slip / 1000);
		fflush(proto);
		if (sim - wall > 200000) {
			take_input(sim - wall); /* ahead: sleep, but take input at once */
		} else {
			if (wall - sim > MAX_BEHIND_NS) {
				slip += wall - sim; /* behind by more than a stall: give the debt up */
				start += wall - sim;
			}
			if (n % 10 == 0)
				take_input(0);
		}
	}
}
