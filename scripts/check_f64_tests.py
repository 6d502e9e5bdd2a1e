#!/usr/bin/env python3
"""Check that the f64 builds of the physics and the CPU backend ran their tests.

Usage: check_f64_tests.py CARGO_TEST_LOG   (the output of `cargo test --workspace`)
       check_f64_tests.py --self-test

rtmpm-physics-f64 and rtmpm-cpu-f64 compile the source files of rtmpm-physics and rtmpm-cpu a
second time with `Real = f64` (`[lib] path`). This fails unless
  * for each of the two, every unit test of the f32 package ran in the f64 package too and
    passed, except those of the modules the f64 package does not compile (PAIRS' third column:
    they do not depend on the precision and the f64 build uses the f32 package's), and at least
    one ran;
  * rtmpm-cpu-f64's tests/precision.rs ran tests (the f64 step against the f32 one and an exact
    free fall) and they passed.
So a crate that silently stops running its tests in f64 (`test = false`, a `cfg` that leaves a
module's tests out, a missing workspace member) fails CI.
"""

import re
import sys

# (f32 test binary, f64 test binary, test-name prefixes of the modules compiled in the f32
# package only). rtmpm-physics: `grid` and `transfer` do not depend on the precision (see its
# lib.rs). rtmpm-cpu: none, every module is compiled in both.
PAIRS = (
    ("rtmpm_physics", "rtmpm_physics_f64", ("grid::", "transfer::")),
    ("rtmpm_cpu", "rtmpm_cpu_f64", ()),
)
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


def compare(secs, f32_bin, f64_bin, f32_only):
    """(problem or None, summary): did every unit test of `f32_bin` outside the `f32_only`
    modules run in `f64_bin` and pass?"""
    f32, f64 = tests_of(secs, f32_bin), tests_of(secs, f64_bin)
    if f32 is None or f64 is None:
        return f"no unit tests of {f32_bin if f32 is None else f64_bin}", None
    wanted = {t for t in f32 if not t.startswith(f32_only)}
    missing = sorted(wanted - set(f64))
    failed = sorted(t for t, r in f64.items() if r != "ok")
    if missing or failed or not f64:
        return (f"{f64_bin}: {len(missing)} tests not run in f64 ({', '.join(missing[:5])}), "
                f"failed: {failed[:5]}"), None
    except_ = f" (all but the {len(f32) - len(wanted)} of {', '.join(f32_only)})" if f32_only else ""
    return None, f"{f32_bin} {len(f32)} unit tests, {f64_bin} {len(f64)}{except_}"


def main(path):
    with open(path, encoding="utf-8", errors="replace") as f:
        secs = sections(f)
    ok = True

    def fail(msg):
        nonlocal ok
        print(f"check_f64_tests: FAIL: {msg}")
        ok = False

    for f32_bin, f64_bin, f32_only in PAIRS:
        problem, summary = compare(secs, f32_bin, f64_bin, f32_only)
        if problem:
            fail(problem)
        else:
            print(f"check_f64_tests: {summary}: ok")
    cpu = tests_of(secs, "precision", "tests/precision.rs")
    if not cpu:
        fail("rtmpm-cpu-f64's tests/precision.rs ran no tests")
    elif any(r != "ok" for r in cpu.values()):
        fail(f"rtmpm-cpu-f64 tests/precision.rs: {cpu}")
    else:
        print(f"check_f64_tests: rtmpm-cpu-f64 tests/precision.rs {len(cpu)} tests: ok")
    return ok


def self_test():
    """The check passes a log where every pair ran, and fails one where a test of rtmpm-cpu did
    not run in f64, or failed there."""
    import os
    import tempfile

    def log(cpu_f64_tests, cpu_f64_outcome="ok"):
        lines = []
        for binary, source, tests, outcome in (
            ("rtmpm_physics", "src/lib.rs", ["svd::tests::a", "grid::codes::tests::b"], "ok"),
            ("rtmpm_physics_f64", "../rtmpm-physics/src/lib.rs", ["svd::tests::a"], "ok"),
            ("rtmpm_cpu", "src/lib.rs", ["tests::a", "tests::steer::b"], "ok"),
            ("rtmpm_cpu_f64", "../rtmpm-cpu/src/lib.rs", cpu_f64_tests, cpu_f64_outcome),
            ("precision", "tests/precision.rs", ["f64_agrees"], "ok"),
        ):
            lines.append(f"     Running unittests {source} (target/debug/deps/{binary}-0123abcd)")
            lines += [f"test {t} ... {outcome}" for t in tests]
        return "\n".join(lines) + "\n"

    def passes(text):
        with tempfile.NamedTemporaryFile("w", suffix=".log", delete=False) as f:
            f.write(text)
        try:
            return main(f.name)
        finally:
            os.unlink(f.name)

    both = ["tests::a", "tests::steer::b"]
    assert passes(log(both))
    assert not passes(log(["tests::a"])), "a test of rtmpm-cpu missing in f64 must fail"
    assert not passes(log([])), "no f64 unit tests must fail"
    assert not passes(log(both, "FAILED")), "a test failed in f64 must fail"
    print("check_f64_tests: self-test ok")
    return True


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    if sys.argv[1] == "--self-test":
        sys.exit(0 if self_test() else 1)
    sys.exit(0 if main(sys.argv[1]) else 1)
