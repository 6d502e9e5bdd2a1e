#!/usr/bin/env bash
# test_agreement alone with the occupancy switch (resident grid + 96 registers), f32 and f64.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache RTMPM_G2P2G_GRID=resident RTMPM_KERNEL_DEFINES="-DG2P2G_MIN_BLOCKS=5 -DG2P2G_FLUID_MIN_BLOCKS=5"
OUT=$R/tv TEST_TIMEOUT=380 TESTS="test_agreement" bash scripts/gpu/run.sh tests > /dev/null 2>&1
cd $R/tv && tar xzf logs.tgz 2>/dev/null; grep -E "^test |test result|max \|dx\||FAIL" test_agreement.log | tail -40 > $R/report.txt; cat summary.txt >> $R/report.txt
cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt -exec rm -rf {} +
cat $R/report.txt
