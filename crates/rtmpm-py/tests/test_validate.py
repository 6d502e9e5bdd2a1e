"""rtmpm.validate(): the published validation cases from Python (the rtmpm-validate crate that
`rtmpm validate` runs too)."""

import pytest

import rtmpm
from conftest import ROOT

SCENES = ROOT / "validation"


def test_free_fall_rows_measure_the_euler_lag(tmp_path):
    # validation/free_fall.toml: g = 9.81 m/s^2, t = 0.4 s, dt = 5e-4 s. Symplectic Euler puts
    # every particle of a free-falling body |g| t dt / 2 below the parabola; the case measures
    # that lag and must find it (not zero, not a different number).
    g, t, dt = 9.81, 0.4, 5e-4
    lag = 0.5 * g * t * dt
    r = rtmpm.validate("free_fall", backend="cpu", quick=True, scenes=SCENES, plots=tmp_path)
    assert r["passed"] is True
    assert r["failed"] == [] and r["broken"] == {}
    rows = r["rows"]
    assert [row["case"] for row in rows] == ["free_fall", "free_fall"]
    pos, deform = rows
    assert pos["reference"] == 0.0 and pos["unit"] == "m"
    assert pos["error"] == pos["simulated"]
    assert abs(pos["error"] - lag) < 0.02 * lag, (pos["error"], lag)
    assert pos["tolerance"] == pytest.approx(lag + 1e-5, rel=1e-5)
    assert pos["passed"] is True
    assert 0.0 <= deform["error"] <= deform["tolerance"] == pytest.approx(1e-4)
    # The command line's table, one line per row after the header.
    lines = r["table"].splitlines()
    assert len(lines) == 3 and lines[1].startswith("free_fall") and lines[1].endswith("PASS")
    assert r["plots"] == []  # free fall draws no plot


def test_unknown_case_lists_the_known_ones():
    with pytest.raises(ValueError) as e:
        rtmpm.validate("free_fal", scenes=SCENES)
    msg = str(e.value)
    assert "free_fal" in msg and "free_fall" in msg and "vibrating_bar" in msg
    assert "free_fall" in rtmpm.validation_cases()
    assert rtmpm.validation_cases()[0] == "free_fall"


def test_bad_arguments_are_value_errors(tmp_path):
    with pytest.raises(ValueError):
        rtmpm.validate("free_fall", backend="gpu", scenes=SCENES)
    with pytest.raises(ValueError):
        rtmpm.validate("free_fall", precision="f16", scenes=SCENES)
    with pytest.raises(ValueError):
        rtmpm.validate(3, scenes=SCENES)
    with pytest.raises(rtmpm.RtmpmError, match="validation scenes not found"):
        rtmpm.validate("free_fall", scenes=tmp_path / "nowhere")
