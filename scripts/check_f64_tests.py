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
    free fall) and they passed;
  * every integration test file of rtmpm-cpu (crates/rtmpm-cpu/tests/NAME.rs, which rtmpm-cpu-f64
    compiles again as the test target NAME_f64) ran in f64 the same tests as in f32, at least
    one, and they passed (a test that does not hold in f64 is ignored there by the source,
    `cfg_attr(feature = "f64", ignore = "why")`, and listed as ignored).
So a crate that silently stops running its tests in f64 (`test = false`, a `cfg` that leaves a
module's tests out, a missing workspace member) fails CI.
"""

import os
import re
import sys

# (f32 test binary, f64 test binary, test-name prefixes of the modules compiled in the f32
# package only). rtmpm-physics: `grid` and `transfer` do not depend on the precision (see its
# lib.rs). rtmpm-cpu: none, every module is compiled in both.
PAIRS = (
    ("rtmpm_physics", "rtmpm_physics_f64", ("grid::", "transfer::")),
    ("rtmpm_cpu", "rtmpm_cpu_f64", ()),
)
# rtmpm-cpu's integration test files (NAME.rs: the f32 target NAME, the f64 target NAME_f64).
CPU_TESTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "crates", "rtmpm-cpu", "tests")
RUNNING = re.compile(r"^\s*Running (.+?) \(.*/deps/([A-Za-z0-9_]+)-[0-9a-f]+(?:\.exe)?\)")
TEST = re.compile(r"^test (\S+) \.\.\. (\w+)")


def sections(lines):
    """{(source, binary, k): {test: outcome}} of a cargo test log (k: the run's place in the log;
    two crates may each have a test binary of the same source and name)."""
    out, current = {}, None
    for line in lines:
        m = RUNNING.match(line)
        if m:
            current = out.setdefault((m.group(1), m.group(2), len(out)), {})
            continue
        if line.lstrip().startswith("Doc-tests "):
            current = None
            continue
        m = TEST.match(line)
        if m and current is not None:
            current[m.group(1)] = m.group(2)
    return out


def tests_of(secs, binary, source=None):
    found = [t for (src, b, _), t in secs.items() if b == binary and (source is None or src.endswith(source))]
    return found[0] if found else None


def compare(secs, f32_bin, f64_bin, f32_only):
    """(problem or None, summary): did every unit test of `f32_bin` outside the `f32_only`
    modules run in `f64_bin` and pass?"""
    f32, f64 = tests_of(secs, f32_bin), tests_of(secs, f64_bin)
    if f32 is None or f64 is None:
        return f"no unit tests of {f32_bin if f32 is None else f64_bin}", None
    wanted = {t for t in f32 if not t.startswith(f32_only)}
    missing = sorted(wanted - set(f64))
    # A test the source ignores in both precisions (`#[ignore]`, e.g. an exploratory printout)
    # is the same in both; one ignored in f64 only is not.
    failed = sorted(t for t, r in f64.items()
                    if r != "ok" and not (r == "ignored" and f32.get(t) == "ignored"))
    if missing or failed or not any(r == "ok" for r in f64.values()):
        return (f"{f64_bin}: {len(missing)} tests not run in f64 ({', '.join(missing[:5])}), "
                f"failed: {failed[:5]}"), None
    except_ = f" (all but the {len(f32) - len(wanted)} of {', '.join(f32_only)})" if f32_only else ""
    return None, f"{f32_bin} {len(f32)} unit tests, {f64_bin} {len(f64)}{except_}"


def integration_names(folder=CPU_TESTS):
    """The integration test files of rtmpm-cpu, without `.rs`."""
    return sorted(f[:-3] for f in os.listdir(folder) if f.endswith(".rs"))


def compare_integration(secs, name):
    """(problem or None, summary): did rtmpm-cpu's tests/NAME.rs run in f64 (NAME_f64) the tests
    it ran in f32, and pass? Other crates may have a tests/NAME.rs of their own: the f32 run is
    the one whose tests are the f64 run's."""
    f64 = tests_of(secs, f"{name}_f64", f"rtmpm-cpu/tests/{name}.rs")
    if not f64:
        return f"rtmpm-cpu tests/{name}.rs ran no tests in f64 (test target {name}_f64)", None
    # A test may be ignored in f64 only, with its reason in the source (`cfg_attr(feature =
    # "f64", ignore = "...")`): it is listed, not run.
    failed = sorted(t for t, r in f64.items() if r not in ("ok", "ignored"))
    if failed or all(r == "ignored" for r in f64.values()):
        return f"rtmpm-cpu tests/{name}.rs failed or did not run in f64: {failed[:5]}", None
    f32_runs = [t for (src, b, _), t in secs.items() if b == name and src == f"tests/{name}.rs"]
    if not any(set(t) == set(f64) for t in f32_runs):
        seen = [sorted(set(t) ^ set(f64))[:5] for t in f32_runs]
        return (f"rtmpm-cpu tests/{name}.rs: the f64 run's tests differ from every f32 run's "
                f"({len(f32_runs)} runs; tests in one only: {seen})"), None
    ignored = sorted(t for t, r in f64.items() if r == "ignored")
    also = f" ({len(ignored)} ignored in f64: {', '.join(ignored)})" if ignored else ""
    return None, f"rtmpm-cpu tests/{name}.rs {len(f64)} tests in f32 and f64{also}"


def main(path, integration=None):
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
    for name in integration_names() if integration is None else integration:
        problem, summary = compare_integration(secs, name)
        if problem:
            fail(problem)
        else:
            print(f"check_f64_tests: {summary}: ok")
    return ok


def self_test():
    """The check passes a log where every pair ran, and fails one where a test of rtmpm-cpu did
    not run in f64, or failed there."""
    import os
    import tempfile

    def log(cpu_f64_tests, cpu_f64_outcome="ok", drop_f64=(), flow_f64=("a", "b"), ignored=()):
        """`ignored`: the unit-test binaries (of rtmpm_cpu, rtmpm_cpu_f64) that list one more
        test, `tests::slow`, as ignored."""
        lines = []
        for binary, source, tests, outcome in (
            ("flow", "tests/flow.rs", ["gpu_only"], "ok"),  # another crate's tests/flow.rs
            ("flow", "tests/flow.rs", ["a", "b"], "ok"),
            ("flow_f64", "../rtmpm-cpu/tests/flow.rs", list(flow_f64), "ok"),
            ("jet", "tests/jet.rs", ["c"], "ok"),
            ("jet_f64", "../rtmpm-cpu/tests/jet.rs", ["c"], "ok"),
            ("rtmpm_physics", "src/lib.rs", ["svd::tests::a", "grid::codes::tests::b"], "ok"),
            ("rtmpm_physics_f64", "../rtmpm-physics/src/lib.rs", ["svd::tests::a"], "ok"),
            ("rtmpm_cpu", "src/lib.rs", ["tests::a", "tests::steer::b"], "ok"),
            ("rtmpm_cpu_f64", "../rtmpm-cpu/src/lib.rs", cpu_f64_tests, cpu_f64_outcome),
            ("precision", "tests/precision.rs", ["f64_agrees"], "ok"),
        ):
            if binary in drop_f64:
                continue
            kind = "unittests " if source.endswith("src/lib.rs") else ""
            lines.append(f"     Running {kind}{source} (target/debug/deps/{binary}-0123abcd)")
            lines += [f"test {t} ... {outcome}" for t in tests]
            if binary in ignored:
                lines.append("test tests::slow ... ignored, exploratory")
        return "\n".join(lines) + "\n"

    def passes(text):
        with tempfile.NamedTemporaryFile("w", suffix=".log", delete=False) as f:
            f.write(text)
        try:
            return main(f.name, integration=["flow", "jet"])
        finally:
            os.unlink(f.name)

    both = ["tests::a", "tests::steer::b"]
    assert passes(log(both))
    assert not passes(log(["tests::a"])), "a test of rtmpm-cpu missing in f64 must fail"
    assert not passes(log([])), "no f64 unit tests must fail"
    assert not passes(log(both, "FAILED")), "a test failed in f64 must fail"
    assert passes(log(both, ignored=("rtmpm_cpu", "rtmpm_cpu_f64"))), "ignored in both passes"
    assert not passes(log(both, ignored=("rtmpm_cpu_f64",))), "ignored in f64 only must fail"
    assert not passes(log(both, "ignored")), "every f64 unit test ignored must fail"
    assert not passes(log(both, drop_f64=("jet_f64",))), "an integration test file not run in f64 must fail"
    assert not passes(log(both, flow_f64=("a",))), "an integration test not run in f64 must fail"
    assert integration_names(), "rtmpm-cpu has integration tests"
    print("check_f64_tests: self-test ok")
    return True


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    if sys.argv[1] == "--self-test":
        sys.exit(0 if self_test() else 1)
    sys.exit(0 if main(sys.argv[1]) else 1)
