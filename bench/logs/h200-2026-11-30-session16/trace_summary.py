"""Session 16: read trace_loop.py's Chrome trace: per mode, the device's busy time, its idle gaps
(between calls and inside them), and the device work a call (kernels by name, copies, memsets)."""
import json, sys, collections
t = json.load(open(sys.argv[1]))
ev = [e for e in t["traceEvents"] if e.get("ph") == "X"]
gpu = [e for e in ev if e.get("cat") in ("kernel", "gpu_memcpy", "gpu_memset")]
cpu = [e for e in ev if e.get("cat") == "user_annotation"]
modes = sorted([e for e in cpu if e["name"].startswith("MODE ")], key=lambda e: e["ts"])
print(f"{len(gpu)} device events, {len(cpu)} annotations")
for m in modes:
    a, z = m["ts"], m["ts"] + m["dur"]
    g = sorted([e for e in gpu if a <= e["ts"] < z], key=lambda e: e["ts"])
    calls = [e for e in cpu if e["name"].endswith(":call") and a <= e["ts"] < z]
    if not g:
        print(m["name"], "no device events"); continue
    busy, gaps, end = 0.0, [], g[0]["ts"]
    for e in g:
        if e["ts"] > end:
            gaps.append(e["ts"] - end)
        busy += e["dur"]; end = max(end, e["ts"] + e["dur"])
    span = end - g[0]["ts"]
    nc = max(1, len(calls))
    print(f"\n== {m['name']}: wall {m['dur']/nc:.0f} us a call ({nc} calls), device span {span/nc:.0f}, busy {busy/nc:.0f} us a call;"
          f" gaps a call: {len(gaps)/nc:.1f}, total {sum(gaps)/nc:.0f} us, >20us: {sum(x for x in gaps if x > 20)/nc:.0f} us")
    big = sorted(gaps, reverse=True)[:8]
    print("   largest gaps (us):", " ".join(f"{x:.0f}" for x in big))
    by = collections.defaultdict(lambda: [0, 0.0])
    for e in g:
        k = (e["cat"], e["name"][:60]); by[k][0] += 1; by[k][1] += e["dur"]
    for (cat, name), (c, d) in sorted(by.items(), key=lambda kv: -kv[1][1])[:25]:
        print(f"   {cat:10s} {c/nc:6.1f}/call {d/nc:8.1f} us/call  {d/c:7.2f} us each  {name}")
    # Host parts a call.
    for part in ("pose", "reset", "step"):
        ps = [e for e in cpu if e["name"] == part and a <= e["ts"] < z]
        if ps:
            print(f"   host {part}: {sum(e['dur'] for e in ps)/len(ps):.0f} us median-ish mean of {len(ps)}")
