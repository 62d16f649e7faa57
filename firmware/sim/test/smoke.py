#!/usr/bin/env python3
"""Smoke test of wtcu-sim against the harness's own test program.
usage: smoke.py [mega|nano] [extra wtcu-sim args...]"""
import os, sys, termios, tty, subprocess, threading, time, select

here = os.path.dirname(os.path.abspath(__file__))
build = os.path.normpath(os.path.join(here, '..', '..', 'build'))
kind = sys.argv[1] if len(sys.argv) > 1 else 'mega'
mcu = 'atmega2560' if kind == 'mega' else 'atmega328p'
elf = os.path.join(build, 'sim-testprog-%s.elf' % kind)
cmd = [os.path.join(build, 'wtcu-sim'), '--mcu', mcu, '--elf', elf] + sys.argv[2:]
p = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
lines = []
first = p.stdout.readline().strip()
print('first line:', first)
assert first.startswith('pty /dev/pts/')
def reader():
    for l in p.stdout:
        lines.append((time.monotonic(), l.strip()))
threading.Thread(target=reader, daemon=True).start()
fd = os.open(first.split()[1], os.O_RDWR | os.O_NOCTTY)
tty.setraw(fd, termios.TCSANOW)
a = termios.tcgetattr(fd); a[4] = a[5] = termios.B115200; termios.tcsetattr(fd, termios.TCSANOW, a)
t_start = time.monotonic()

def rd(timeout, until=None):
    buf = b''
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        r, _, _ = select.select([fd], [], [], 0.05)
        if r:
            buf += os.read(fd, 4096)
            if until is not None and until(buf):
                break
    return buf

def sendcmd(b, expect_nl=True, timeout=3):
    os.write(fd, b)
    return rd(timeout, (lambda x: x.endswith(b'\n')) if expect_nl else (lambda x: len(x) >= len(b)))

print('boot:', rd(1.0, lambda x: b'BOOT\n' in x))
# echo of a burst of 600 bytes (no 0x01), with zeros in it
burst = bytes((i * 7 + 3) % 256 for i in range(600)).replace(b'\x01', b'\x02')
t0 = time.monotonic()
os.write(fd, burst)
got = rd(5, lambda x: len(x) >= len(burst))
print('burst: sent %d got %d identical=%s in %.3f s wall' % (len(burst), len(got), got == burst, time.monotonic() - t0))
print('pins cmd:', sendcmd(b'\x01P\x09\x90', expect_nl=False))
time.sleep(0.2)
print('pins cmd:', sendcmd(b'\x01P\x00\x00', expect_nl=False))
print('adc:', sendcmd(b'\x01A'))
p.stdin.write('battery 3300\n'); p.stdin.flush(); time.sleep(0.05)
print('adc after battery 3300:', sendcmd(b'\x01A'))
print('i2c:', sendcmd(b'\x01I'))
p.stdin.write('mag -30 15.5 -45\naccel 0.5,-0.25,1.999\n'); p.stdin.flush(); time.sleep(0.05)
print('i2c after mag/accel cmd:', sendcmd(b'\x01I'))
# realtime check
s0 = [l for l in lines]; w0 = time.monotonic()
os.write(fd, b'\x00'); rd(0.3)
time.sleep(2.0)
os.write(fd, b'\x00'); rd(0.3)
w1 = time.monotonic()
rx = [int(l.split()[1]) for _, l in lines if l.startswith('rx ')]
print('rx lines:', rx[-2:], 'sim delta us = %d, wall delta = %.0f us' % (rx[-1] - rx[-2], 1e6 * 2.3))
print('watchdog:', sendcmd(b'\x01W'))
time.sleep(0.6)
print('after wdt:', rd(0.5))
p.stdin.write('quit\n'); p.stdin.flush()
p.wait(timeout=5)
time.sleep(0.1)
for t, l in lines:
    print('  [%.3f] %s' % (t - t_start, l))
print('exit code', p.returncode)
