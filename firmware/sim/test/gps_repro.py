#!/usr/bin/env python3
"""GPS forwarding check against wtcu-sim running the real firmware (Mega).
usage: gps_repro.py [seconds] [extra wtcu-sim args...]
Opens a v2 session, GPS_START 9600, feeds the watchdog, reassembles the GPS_DATA
stream and compares it with the GPS log (looped by the harness). Exit 1 on any
silent loss (bytes missing that `lost` does not account for)."""
import os, sys, termios, tty, subprocess, threading, time, select

here = os.path.dirname(os.path.abspath(__file__))
root = os.path.normpath(os.path.join(here, '..', '..', '..'))
build = os.path.join(root, 'firmware', 'build')
log_path = os.path.join(root, 'tests', 'data', 'gpsd-logs', 'bu353s4.log')
secs = float(sys.argv[1]) if len(sys.argv) > 1 else 30.0
BAUD = int(os.environ.get('GPS_BAUD', '9600'))
cmd = [os.environ.get('WTCU_SIM', os.path.join(build, 'wtcu-sim')), '--mcu', 'atmega2560', '--elf',
       os.path.join(build, 'wtcu-mega.elf'), '--gps', log_path, '--gps-baud', str(BAUD)] + sys.argv[2:]
LOG = open(log_path, 'rb').read()

def crc16(d):
    c = 0xFFFF
    for b in d:
        c ^= b << 8
        for _ in range(8):
            c = ((c << 1) ^ 0x1021) & 0xFFFF if c & 0x8000 else (c << 1) & 0xFFFF
    return c

def cobs_enc(s):
    out, blk = bytearray(), bytearray()
    for b in s:
        if b == 0:
            out += bytes([len(blk) + 1]) + blk; blk = bytearray()
        else:
            blk.append(b)
            if len(blk) == 254:
                out += bytes([255]) + blk; blk = bytearray()
    out += bytes([len(blk) + 1]) + blk
    return bytes(out)

def cobs_dec(s):
    out, i = bytearray(), 0
    while i < len(s):
        c = s[i]; i += 1
        if c == 0: return None
        out += s[i:i + c - 1]; i += c - 1
        if c != 255 and i < len(s): out.append(0)
    return bytes(out)

def frame(typ, seq, payload=b''):
    pkt = bytes([2, typ, seq, len(payload)]) + payload
    c = crc16(pkt)
    return b'\x00' + cobs_enc(pkt + bytes([c & 0xFF, c >> 8])) + b'\x00'

HELLO = bytes.fromhex('00 03 02 01 01 03 98 5e 00')
GPS_START = bytes.fromhex('00 07 02 0b 04 04 80 25 01 03 1e ca 00')
assert frame(0x0B, 4, (9600).to_bytes(4, 'little')) == GPS_START, frame(0x0B, 4, (9600).to_bytes(4, 'little')).hex()

p = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, bufsize=1)
first = p.stdout.readline().strip()
assert first.startswith('pty '), first
err_lines = []
def drain(f, dst):
    for l in f:
        dst.append(l.rstrip('\n'))
threading.Thread(target=drain, args=(p.stdout, []), daemon=True).start()
threading.Thread(target=drain, args=(p.stderr, err_lines), daemon=True).start()
fd = os.open(first.split()[1], os.O_RDWR | os.O_NOCTTY)
tty.setraw(fd, termios.TCSANOW)

buf = bytearray()
frames = []
def pump(t):
    end = time.monotonic() + t
    while True:
        left = end - time.monotonic()
        if left <= 0: break
        r, _, _ = select.select([fd], [], [], left)
        if r: buf.extend(os.read(fd, 65536))
    parts = bytes(buf).split(b'\x00')
    buf[:] = parts[-1]
    for body in parts[:-1]:
        if not body: continue
        d = cobs_dec(body)
        if d is None or len(d) < 6 or crc16(d[:-2]) != d[-2] | d[-1] << 8:
            frames.append(('bad', body)); continue
        frames.append((d[1], d[2], d[4:4 + d[3]]))

pump(0.5)
os.write(fd, HELLO); pump(0.2)
os.write(fd, frame(0x0B, 4, BAUD.to_bytes(4, 'little'))); pump(0.1)
t0 = time.monotonic(); seq = 10; nexthb = t0
while time.monotonic() - t0 < secs:
    if time.monotonic() >= nexthb:
        os.write(fd, frame(0x02, seq & 0xFF)); seq += 1; nexthb += 0.25
    pump(max(0.0, min(0.05, nexthb - time.monotonic())))
pump(0.3)
p.stdin.write('quit\n'); p.stdin.flush()
try: p.wait(timeout=5)
except subprocess.TimeoutExpired: p.kill()

gps = [f for f in frames if f[0] == 0x87]
bad = [f for f in frames if f[0] == 'bad']
types = {}
for f in frames: types[f[0]] = types.get(f[0], 0) + 1
stream = b''.join(f[2][2:] for f in gps)
lost_total = sum(f[2][0] | f[2][1] << 8 for f in gps)
# align the stream on the looped log
L = LOG * (len(stream) // len(LOG) + 3)
start = L.find(stream[:16]) if len(stream) >= 16 else -1
pos, i, missing, extra, events = start, 0, 0, 0, []
while i < len(stream) and start >= 0 and pos + 220 < len(L):
    if stream[i] == L[pos]:
        i += 1; pos += 1; continue
    for k in range(1, 200):   # k bytes missing?
        if stream[i:i + 5] == L[pos + k:pos + k + 5]:
            missing += k; events.append((i, 'missing', k, L[pos - 20:pos + k + 10])); pos += k; break
    else:
        extra += 1; events.append((i, 'extra', 1, stream[i - 10:i + 10])); i += 1
print('frames: %s bad=%d' % ({hex(k) if isinstance(k, int) else k: v for k, v in types.items()}, len(bad)))
print('GPS_DATA frames %d, bytes %d over %.1f s, lost reported %d, missing %d, extra %d, start offset %d' %
      (len(gps), len(stream), secs, lost_total, missing, extra, start))
for e in events[:15]: print('  at', e)
for l in err_lines:
    if 'overrun' in l or 'warning' in l or 'drop' in l or 'GPS' in l or 'simavr' in l: print('  sim:', l)
silent = missing - lost_total
ok = start >= 0 and extra == 0 and missing == lost_total
print('RESULT: %s (silent loss %d)' % ('OK' if ok else 'FAIL', silent))
sys.exit(0 if ok else 1)
