"""Simulation.view(): the live view of `rtmpm view` from Python, on the CPU backend. The browser
path is served on a free local port and read over HTTP (the page, /status) and through the
LiveView's own status and commands; the window path opens under Xvfb (skipped where Xvfb is not
installed; CI installs it in scripts/check_window.sh, which runs before the Python stage)."""

import json
import os
import shutil
import socket
import subprocess
import time
import urllib.request

import numpy as np
import pytest

import rtmpm


def wait_for(cond, seconds=60.0, what="the condition"):
    t0 = time.monotonic()
    while time.monotonic() - t0 < seconds:
        v = cond()
        if v:
            return v
        time.sleep(0.05)
    raise AssertionError(f"timed out after {seconds} s waiting for {what}")


def get(url):
    with urllib.request.urlopen(url, timeout=30) as r:
        return r.status, r.read()


@pytest.fixture
def sim(small_path):
    s = rtmpm.Simulation(small_path, backend="cpu", threads=2)
    s.run_frame()
    return s


def test_view_serves_a_copy_of_the_simulation_and_stops(sim):
    x0, t0 = sim.particles.x.copy(), sim.time
    view = sim.view(serve="127.0.0.1:0", size=(160, 90))
    try:
        assert view.running and view.url.startswith("http://127.0.0.1:")
        assert view.url.rstrip("/").rsplit(":", 1)[1] != "0"  # the port the system picked
        status, page = get(view.url)
        assert status == 200 and b"<html" in page.lower()
        # The copy starts where the simulation is and moves on by itself.
        first = wait_for(lambda: view.status, what="a first picture")
        assert first["frame"] >= 1 and first["time"] >= t0 - 1e-9
        assert (first["width"], first["height"]) == (160, 90)
        assert first["particles"] == sim.num_particles and first["backend"].startswith("cpu")
        wait_for(lambda: view.status["frame"] >= first["frame"] + 2, what="frames to pass")
        _, body = get(view.url + "status")
        assert json.loads(body)["frame"] >= first["frame"] + 2
        assert "LiveView(url=" in repr(view) and view.url in view._repr_html_()
    finally:
        summary = view.stop()
    assert not view.running and view.stop() is None
    assert summary["pictures"] >= 3 and summary["frames"] >= 3 and summary["error"] is None
    # The Simulation object did not move on.
    assert sim.time == t0 and np.array_equal(sim.particles.x, x0)
    sim.run_frame()


def test_view_is_steered_like_the_page(sim):
    with sim.view(serve="127.0.0.1:0", size=(160, 90), paused=True) as view:
        s = wait_for(lambda: view.status, what="a first picture")
        assert s["paused"] and s["frame"] == sim.frame
        step0 = s["step"]
        view.send({"cmd": "step"})
        wait_for(lambda: view.status["step"] == step0 + 1, what="one step")
        time.sleep(0.3)
        assert view.status["step"] == step0 + 1, "paused: one step only"
        view.send('{"cmd": "gravity", "value": [1.0, 0.0, 0.0]}')
        wait_for(lambda: view.status["gravity"] == [1.0, 0.0, 0.0], what="gravity")
        view.send({"cmd": "color_by", "value": "speed"})
        wait_for(lambda: view.status["color_by"] == "speed", what="the colour mode")
        view.send({"cmd": "resume"})
        wait_for(lambda: view.status["step"] > step0 + 5, what="steps after resuming")
        with pytest.raises(ValueError, match="cmd"):
            view.send({"cmd": "explode"})
        with pytest.raises(ValueError):
            view.send({"cmd": "gravity", "value": [0, "up", 0]})
    assert not view.running
    with pytest.raises(rtmpm.RtmpmError, match="ended"):
        view.send({"cmd": "pause"})


def test_view_ends_after_its_frames(sim):
    view = sim.view(serve="127.0.0.1:0", size=(64, 36), frames=2)
    summary = view.wait(timeout=120)
    assert summary is not None, "the view ended by itself"
    assert summary["frames"] == sim.frame + 2 and summary["pictures"] >= 1
    assert not view.running and view.wait() is None


def test_view_refuses_bad_arguments(sim):
    with pytest.raises(ValueError, match="HOST:PORT|address"):
        sim.view(serve="not an address")
    with pytest.raises(ValueError, match="serve"):
        sim.view(serve=12)
    with pytest.raises(ValueError, match="colour|color"):
        sim.view(serve="127.0.0.1:0", color_by="temperature")
    with pytest.raises(ValueError, match="frames"):
        sim.view(serve="127.0.0.1:0", frames=0)
    with pytest.raises(ValueError, match="size"):
        sim.view(serve="127.0.0.1:0", size=(8, 8))
    # A port in use: a clear error, nothing started.
    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen(1)
    try:
        port = busy.getsockname()[1]
        with pytest.raises(rtmpm.RtmpmError, match=str(port)):
            sim.view(serve=f"127.0.0.1:{port}")
    finally:
        busy.close()


def test_view_without_a_display_asks_for_the_browser(sim, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(rtmpm.RtmpmError, match="serve=True"):
        sim.view(serve=False)


def x_server_answers(display):
    """Whether the X server on `display` answers a client (its socket file appears before it
    has set up its screen); xdpyinfo where installed, else the socket file alone."""
    if shutil.which("xdpyinfo") is None:
        return os.path.exists(f"/tmp/.X11-unix/X{display.lstrip(':')}")
    env = dict(os.environ, DISPLAY=display)
    return subprocess.run(["xdpyinfo"], env=env, stdout=subprocess.DEVNULL,
                          stderr=subprocess.DEVNULL).returncode == 0


@pytest.fixture
def xvfb(monkeypatch):
    """An X server without a screen on a free display number, as DISPLAY."""
    if shutil.which("Xvfb") is None:
        pytest.skip("Xvfb is not installed (scripts/check_window.sh installs it)")
    n = 120
    while os.path.exists(f"/tmp/.X11-unix/X{n}") or os.path.exists(f"/tmp/.X{n}-lock"):
        n += 1
    proc = subprocess.Popen(
        ["Xvfb", f":{n}", "-screen", "0", "640x480x24", "-nolisten", "tcp", "-noreset"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        wait_for(lambda: x_server_answers(f":{n}"), 20, "Xvfb")
        monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
        monkeypatch.setenv("DISPLAY", f":{n}")
        yield f":{n}"
    finally:
        proc.terminate()
        proc.wait(10)


def test_view_opens_a_window_where_there_is_a_display(sim, xvfb):
    """The window front-end (winit + softbuffer) under Xvfb: it opens, shows the view's
    pictures and closes by itself when the view's frames are done."""
    t0 = time.monotonic()
    summary = sim.view(size=(160, 90), frames=2)
    assert isinstance(summary, dict), "a window, not the browser"
    assert summary["frames"] == sim.frame + 2 and summary["pictures"] >= 2
    assert summary["error"] is None and time.monotonic() - t0 < 120
    # A second window from the same thread reuses the event loop.
    again = sim.view(serve=False, size=(64, 36), frames=1)
    assert again["frames"] == sim.frame + 1
