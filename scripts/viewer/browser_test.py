#!/usr/bin/env python3
"""The browser path of `rtmpm view` in a real browser.

Starts `rtmpm view SCENE --serve 127.0.0.1:0 --backend cpu`, opens its page in headless
Chromium (Debian's /usr/bin/chromium, driven by Playwright; no browser is downloaded) and
checks, from what the page shows and the status the server streams with every picture:

* pictures arrive and change while the simulation runs;
* Pause stops the simulated time; Step advances exactly one step; Reset returns to t = 0;
* dragging the tool (Shift + left drag) through the sand moves the sand along the drag,
  against the same run without the drag;
* a second page watches, and its commands are refused politely;
* the keyboard works (Space resumes); Throw adds a ball of the chosen material.

Optionally saves a screenshot of the page (--screenshot PNG). Exits non-zero on the first
failed check, with what was seen.
"""

import argparse
import math
import os
import re
import subprocess
import sys
import tempfile
import time

CHROMIUM_FLAGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
]


def log(*a):
    print("browser test:", *a, flush=True)


class Failed(Exception):
    pass


def check(ok, what):
    if not ok:
        raise Failed(what)
    log("ok:", what)


# ---------------------------------------------------------------------------- the camera
# The first camera of `rtmpm view` (rtmpm_render::Camera::framing on the domain's
# interior), to aim the mouse at a point of the scene.


def sub(a, b):
    return [x - y for x, y in zip(a, b)]


def add(a, b):
    return [x + y for x, y in zip(a, b)]


def mul(a, s):
    return [x * s for x in a]


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def norm(a):
    n = math.sqrt(dot(a, a))
    return [x / n for x in a]


def framing(lo, hi, aspect, fov=40.0):
    center = mul(add(lo, hi), 0.5)
    d = norm([0.55, 0.5, 1.0])
    tan_v = math.tan(math.radians(fov) / 2)
    tan_h = tan_v * aspect
    fwd = mul(d, -1)
    right = norm(cross(fwd, [0, 1, 0]))
    up = cross(right, fwd)
    dist = 1e-6
    for i in range(8):
        c = [hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1], hi[2] if i & 4 else lo[2]]
        o = sub(c, center)
        need = dot(o, d) + max(abs(dot(o, right)) / tan_h, abs(dot(o, up)) / tan_v)
        dist = max(dist, need)
    return add(center, mul(d, 1.05 * dist)), center, fov


def project(cam, w, h, p):
    pos, target, fov = cam
    fwd = norm(sub(target, pos))
    right = norm(cross(fwd, [0, 1, 0]))
    up = cross(right, fwd)
    focal = 0.5 * h / math.tan(math.radians(fov) / 2)
    d = sub(p, pos)
    z = dot(d, fwd)
    return 0.5 * w + dot(d, right) * focal / z, 0.5 * h - dot(d, up) * focal / z


# ---------------------------------------------------------------------------- the server


def start_server(rtmpm, scene, size):
    cmd = [rtmpm, "view", scene, "--serve", "127.0.0.1:0", "--backend", "cpu",
           "--size", size]
    log("starting:", " ".join(cmd))
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    deadline = time.time() + 300
    seen = []
    while time.time() < deadline:
        line = proc.stderr.readline()
        if not line:
            break
        seen.append(line.rstrip())
        m = re.search(r"open (http://127\.0\.0\.1:\d+/)", line)
        if m:
            return proc, m.group(1)
    proc.kill()
    raise Failed("the server did not start; it said:\n" + "\n".join(seen))


def stop_server(proc):
    proc.send_signal(2)  # Ctrl-C: it finishes cleanly
    try:
        out = proc.communicate(timeout=30)[1]
    except subprocess.TimeoutExpired:
        proc.kill()
        raise Failed("the server did not stop within 30 s of Ctrl-C")
    log("server said at the end:", out.strip().replace("\n", " | "))
    check(proc.returncode == 0, f"the server exits cleanly on Ctrl-C (status {proc.returncode})")


# ---------------------------------------------------------------------------- the page


def status(page):
    return page.evaluate("() => window.rtmpm.status")


def wait_status(page, pred, what, timeout=60.0):
    deadline = time.time() + timeout
    s = None
    while time.time() < deadline:
        s = status(page)
        if s is not None and pred(s):
            return s
        time.sleep(0.05)
    raise Failed(f"{what}: not seen within {timeout} s; last status {s}")


def canvas_sum(page):
    """A checksum of the canvas' pixels."""
    return page.evaluate("""() => {
        const c = document.getElementById('view');
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let s = 0;
        for (let i = 0; i < d.length; i += 7) s = (s * 31 + d[i]) % 1000000007;
        return s;
    }""")


def drag_tool(page, a, b, steps=12, hold=1.0):
    """Shift + left drag on the canvas from picture pixel a to b."""
    box = page.locator("#view").bounding_box()
    size = page.evaluate("() => [document.getElementById('view').width, "
                         "document.getElementById('view').height]")
    sx, sy = box["width"] / size[0], box["height"] / size[1]
    to_page = lambda p: (box["x"] + p[0] * sx, box["y"] + p[1] * sy)
    page.keyboard.down("Shift")
    page.mouse.move(*to_page(a))
    page.mouse.down()
    for i in range(1, steps + 1):
        t = i / steps
        page.mouse.move(*to_page((a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t)))
        time.sleep(0.08)
    time.sleep(hold)
    page.mouse.up()
    page.keyboard.up("Shift")


def run(args):
    from playwright.sync_api import sync_playwright

    w, h = (int(x) for x in args.size.split("x"))
    # The scene's interior (sandbox.toml: domain minus 3 walls of dx 0.04).
    lo, hi = [0.12, 0.12, 0.12], [0.88, 0.48, 0.68]
    cam = framing(lo, hi, w / h)
    proc, url = start_server(args.rtmpm, args.scene, args.size)
    log("page at", url)
    try:
        with sync_playwright() as p, tempfile.TemporaryDirectory() as profile:
            browser = p.chromium.launch_persistent_context(
                profile, executable_path=args.chromium, headless=True, args=CHROMIUM_FLAGS,
                viewport={"width": w + 40, "height": h + 260})
            page = browser.pages[0] if browser.pages else browser.new_page()
            errors = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(url)
            browse(page, browser, cam, w, h, args)
            check(not errors, f"no script errors on the page {errors}")
            browser.close()
    finally:
        if proc.poll() is None:
            stop_server(proc)


def browse(page, browser, cam, w, h, args):
    # Pictures arrive and change.
    page.wait_for_function("() => window.rtmpm.frames >= 3", timeout=120_000)
    s0 = status(page)
    check(s0["width"] == w and s0["height"] == h, f"pictures of {w}x{h} arrive")
    c0 = canvas_sum(page)
    f0 = page.evaluate("() => window.rtmpm.frames")
    wait_status(page, lambda s: s["time"] > s0["time"] + 0.1, "the time goes on")
    page.wait_for_function(f"() => window.rtmpm.frames >= {f0 + 3}", timeout=60_000)
    check(canvas_sum(page) != c0, "the picture changes while the simulation runs")
    check(page.evaluate("() => window.rtmpm.role") == "controller", "the first page controls")

    # Pause: the time stops.
    page.click("#pause")
    p = wait_status(page, lambda s: s["paused"], "paused after the Pause button")
    time.sleep(1.5)
    q = status(page)
    check(q["time"] == p["time"] and q["step"] == p["step"],
          f"paused time stops (t = {p['time']:.4f} s, step {p['step']}, 1.5 s later "
          f"t = {q['time']:.4f} s, step {q['step']})")

    # Step: one step.
    page.click("#step")
    st = wait_status(page, lambda s: s["step"] > p["step"], "a step after the Step button")
    time.sleep(0.5)
    st = status(page)
    check(st["step"] == p["step"] + 1 and st["time"] > p["time"],
          f"Step advances one step ({p['step']} -> {st['step']})")

    # Reset: t = 0.
    page.click("#reset")
    r = wait_status(page, lambda s: s["step"] == 0, "reset")
    check(r["time"] == 0.0 and r["frame"] == 0, "Reset returns to t = 0")

    # A second page watches; its commands are refused politely.
    other = browser.new_page()
    other.goto(page.url)
    other.wait_for_function("() => window.rtmpm.role !== null && window.rtmpm.frames >= 1",
                            timeout=60_000)
    check(other.evaluate("() => window.rtmpm.role") == "viewer", "a second page watches")
    other.click("#step")
    other.wait_for_function("() => window.rtmpm.lastError !== null", timeout=30_000)
    err = other.evaluate("() => window.rtmpm.lastError")
    check("another client controls" in err, f"its commands are refused politely: {err!r}")
    time.sleep(0.5)
    check(status(page)["step"] == 0, "the refused step did not step")
    other.close()

    # The drag: run 1 s of simulated time without and with the tool dragged through the sand
    # bed (Shift + left drag from its front face towards the right), from t = 0 each time.
    def settle_and_measure(drag):
        page.click("#reset")
        wait_status(page, lambda s: s["step"] == 0, "reset")
        page.keyboard.press("Space")  # resume, by the keyboard
        wait_status(page, lambda s: not s["paused"], "resumed by Space")
        if drag:
            a = project(cam, w, h, [0.2, 0.22, 0.68])
            b = (a[0] + 0.25 * w, a[1])
            drag_tool(page, a, b)
        s = wait_status(page, lambda s: s["time"] >= 1.0, "1 s simulated", timeout=300)
        page.click("#pause")
        wait_status(page, lambda s: s["paused"], "paused")
        return s

    free = settle_and_measure(False)
    dragged = settle_and_measure(True)
    cf, cd = free["center_of_mass"], dragged["center_of_mass"]
    # Screen-right is world +x (and a little -z) for the first camera.
    dx = cd[0] - cf[0]
    check(dx > 0.005, f"the drag moved the sand along it: centre of mass x {cf[0]:.4f} without, "
          f"{cd[0]:.4f} with the drag (+{dx:.4f} m)")
    # A ball of water thrown in (the Throw button: through the picture's centre).
    n = dragged["particles"]
    page.select_option("#material", "water")
    page.click("#throw")
    t = wait_status(page, lambda s: s["particles"] > n, "a thrown ball")
    check("water" in (t["message"] or ""), f"Throw adds a ball of water: {t['message']!r}")
    if args.screenshot:
        page.click("#pause")
        wait_status(page, lambda s: not s["paused"], "resumed")
        time.sleep(1.0)
        page.screenshot(path=args.screenshot)
        log("screenshot:", args.screenshot)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rtmpm", default="target/debug/rtmpm")
    ap.add_argument("--scene", default="scenes/sandbox.toml")
    ap.add_argument("--size", default="480x270")
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    ap.add_argument("--screenshot", help="save a screenshot of the page here (PNG)")
    args = ap.parse_args()
    if not os.access(args.chromium, os.X_OK):
        sys.exit(f"browser test: no Chromium at {args.chromium} (apt-get install chromium)")
    t0 = time.time()
    try:
        run(args)
    except Failed as e:
        log("FAILED:", e)
        sys.exit(1)
    log(f"all checks passed in {time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
