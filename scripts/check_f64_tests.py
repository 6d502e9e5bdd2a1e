#!/usr/bin/env python3
"""Check that the f64 builds of the physics and the CPU backend ran their tests.

Usage: check_f64_tests.py CARGO_TEST_LOG   (the output of `cargo test --workspace`)

rtmpm-physics-f64 and rtmpm-cpu-f64 compile the source files of rtmpm-physics and rtmpm-cpu a
second time with `Real = f64` (`[lib] path`). This fails unless
  * every unit test of rtmpm-physics ran in rtmpm-physics-f64 too and passed, except those of
    the modules the f64 build does not compile (F32_ONLY: they do not depend on the precision
    and the f64 build uses the f32 package's), and at least one ran;
  * rtmpm-cpu-f64's tests/precision.rs ran tests (the f64 step against the f32 one and an exact
    free fall) and they passed. rtmpm-cpu's unit tests are written for f32 (particles and step
    constants built by hand, bit-exact comparisons) and are compiled out of the f64 build.
So a crate that silently stops running its tests in f64 (`test = false`, a `cfg` that leaves a
module's tests out, a missing workspace member) fails CI.
"""

import re
import sys

# Modules of rtmpm-physics compiled in the f32 package only (see its lib.rs).
F32_ONLY = ("grid::", "transfer::")
RUNNING = re.compile(r"^\s*Running (.+?) \(.*/deps/([A-Za-z0-9_]+)-[0-9a-f]+(?:\.exe)?\)")
TEST = re.compile(r"^test (\S+) \.\.\. (\w+)")


def sections(lines):
    """{(source, binary): {test: outcome}} of a cargo test log."""
    out, current = {}, None
    for line in lines:
        m = RUNNING.match(line)
        if m:
            current = out.setdefault((m.group(1), m.group(2)), {})
            continue
        if line.lstrip().startswith("Doc-tests "):
            current = None
            continue
        m = TEST.match(line)
        if m and current is not None:
            current[m.group(1)] = m.group(2)
    return out


def tests_of(secs, binary, source=None):
    found = [t for (src, b), t in secs.items() if b == binary and (source is None or src.endswith(source))]
    return found[0] if found else None


def main(path):
    with open(path, encoding="utf-8", errors="replace") as f:
        secs = sections(f)
    ok = True

    def fail(msg):
        nonlocal ok
        print(f"check_f64_tests: FAIL: {msg}")
        ok = False

    f32, f64 = tests_of(secs, "rtmpm_physics"), tests_of(secs, "rtmpm_physics_f64")
    if f32 is None or f64 is None:
        fail(f"no unit tests of {'rtmpm_physics' if f32 is None else 'rtmpm_physics_f64'} in {path}")
    else:
        wanted = {t for t in f32 if not t.startswith(F32_ONLY)}
        missing = sorted(wanted - set(f64))
        failed = sorted(t for t, r in f64.items() if r != "ok")
        if missing or failed or not f64:
            fail(f"rtmpm-physics-f64: {len(missing)} tests not run in f64 ({', '.join(missing[:5])}), failed: {failed[:5]}")
        else:
            print(f"check_f64_tests: rtmpm-physics {len(f32)} unit tests, rtmpm-physics-f64 {len(f64)} "
                  f"(all but the {len(f32) - len(wanted)} of {', '.join(F32_ONLY)}): ok")
    cpu = tests_of(secs, "precision", "tests/precision.rs")
    if not cpu:
        fail("rtmpm-cpu-f64's tests/precision.rs ran no tests")
    elif any(r != "ok" for r in cpu.values()):
        fail(f"rtmpm-cpu-f64 tests/precision.rs: {cpu}")
    else:
        print(f"check_f64_tests: rtmpm-cpu-f64 tests/precision.rs {len(cpu)} tests: ok")
    return ok


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    sys.exit(0 if main(sys.argv[1]) else 1)
