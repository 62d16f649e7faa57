"""Independent readers for vestnav's lab outputs (tests/lab.rs).

lsl PREFIX M P H V: resolve the four streams PREFIX-{markers,position,heading,vest} with pylsl, print
"ready" once every inlet is subscribed, then print one JSON line per sample received
({"stream", "t" (the sample's timestamp), "tc" (the inlet's clock offset), "value"}) until M markers,
P positions, H headings and V vest events arrived (or 20 s passed), then "done".

osc: read hex-encoded UDP datagrams from stdin, one per line; print each as JSON [address, [args...]] as
python-osc decodes it.
Exit 3 when the reader's library is not installed.
"""
import json
import sys
import time


def lsl(prefix, want):
    try:
        import pylsl
    except ImportError as e:
        print(f"pylsl not installed: {e}", file=sys.stderr)
        sys.exit(3)
    names = ["markers", "position", "heading", "vest"]
    inlets = {}
    for n in names:
        found = pylsl.resolve_byprop("name", f"{prefix}-{n}", 1, 10.0)
        if not found:
            print(f"stream {prefix}-{n} not found", file=sys.stderr)
            sys.exit(2)
        inlet = pylsl.StreamInlet(found[0], max_buflen=60)
        inlet.open_stream(timeout=10.0)
        inlets[n] = inlet
    info = inlets["position"].info(timeout=5.0)
    labels = []
    ch = info.desc().child("channels").child("channel")
    while not ch.empty():
        labels.append((ch.child_value("label"), ch.child_value("unit")))
        ch = ch.next_sibling()
    print(json.dumps({"labels": labels, "version": pylsl.library_version()}), flush=True)
    tc = {n: inlets[n].time_correction(timeout=5.0) for n in names}
    print("ready", flush=True)
    got = dict.fromkeys(names, 0)
    end = time.monotonic() + 20.0
    while time.monotonic() < end and any(got[n] < want[n] for n in names):
        idle = True
        for n in names:
            sample, t = inlets[n].pull_sample(timeout=0.0)
            if sample is not None:
                idle = False
                got[n] += 1
                # JSON has no NaN: an unknown accuracy goes as null.
                sample = [None if isinstance(x, float) and x != x else x for x in sample]
                print(json.dumps({"stream": n, "t": t, "tc": tc[n], "value": sample}), flush=True)
        if idle:
            time.sleep(0.001)
    print("done", flush=True)


def osc():
    try:
        from pythonosc.osc_message import OscMessage
    except ImportError as e:
        print(f"python-osc not installed: {e}", file=sys.stderr)
        sys.exit(3)
    for line in sys.stdin:
        line = line.strip()
        if line:
            m = OscMessage(bytes.fromhex(line))
            print(json.dumps([m.address, list(m.params)]), flush=True)


if __name__ == "__main__":
    if sys.argv[1] == "lsl":
        want = dict(zip(["markers", "position", "heading", "vest"], map(int, sys.argv[3:7])))
        lsl(sys.argv[2], want)
    else:
        osc()
