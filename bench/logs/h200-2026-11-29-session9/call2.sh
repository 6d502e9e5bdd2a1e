#!/usr/bin/env bash
# Session 9, call 2 (binaries and wheel of main 77313bf): the Python package's GPU tests in full
# (tests/test_gpu.py, cut at test_gpu_agrees_with_the_cpu in session 8, and tests/test_batch_gpu.py),
# then the hostile-input corpus with its run cases on the CUDA backend (scripts/gpu/reliability.sh).
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
SITE=$(mktemp -d)
python3 -m pip install --quiet --no-index --no-deps --target "$SITE" .device/wheels/rtmpm-*.whl
export PYTHONPATH="$SITE" RTMPM_CLI=$PWD/.device/rtmpm
python3 -c 'import rtmpm, sys; print("rtmpm", rtmpm.__version__, "python", sys.version.split()[0], "cuda", rtmpm.cuda_available())' >> $R/summary.txt 2>&1
timeout 260 python3 -m pytest -v -p no:cacheprovider crates/rtmpm-py/tests/test_gpu.py crates/rtmpm-py/tests/test_batch_gpu.py \
  > $R/pytest.log 2>&1
echo "pytest test_gpu.py test_batch_gpu.py rc=$? (limit 260 s): $(tail -1 $R/pytest.log)" >> $R/summary.txt
grep -E "PASSED|FAILED|SKIPPED|ERROR" $R/pytest.log | sed -E 's/ +\[ *[0-9]+%\]//' >> $R/summary.txt
el python
OUT=$R/rel timeout 270 bash scripts/gpu/reliability.sh > $R/reliability.txt 2>&1
echo "reliability rc=$?" >> $R/summary.txt; cat $R/reliability.txt >> $R/summary.txt
{ echo "verdicts so far:"; awk 'NF>2 {print $1}' $R/rel/hostile_cuda.log | sort | uniq -c;
  grep -E "^(crash|hang|lost|unclear|silent|setup-failed) " $R/rel/hostile_cuda.log | head -20; tail -2 $R/rel/hostile_cuda.log; } >> $R/summary.txt 2>/dev/null
el reliability
{ cat $R/summary.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
