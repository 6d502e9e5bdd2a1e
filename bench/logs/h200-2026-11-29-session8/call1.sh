#!/usr/bin/env bash
# Session 8, call 1 (binaries of main c0ba1c8): the granular column with CK-MPM at full resolution
# run twice as long (1.2 s) with the deposit's motion history; the stream of the snow 1.33M with two
# JPEG encoder threads (received / simulated frames); the CK-MPM agreement test in full.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
# The test binaries find the repository through the path they were built in (as run.sh does).
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
rm -rf /tmp/valg && cp -r validation /tmp/valg
sed -i 's/^duration = 0.6/duration = 1.2/' /tmp/valg/granular_column.toml
grep -n "^duration" /tmp/valg/granular_column.toml > $R/granular.txt
timeout 200 $D/rtmpm validate --backend cuda --case granular_column_ck --scenes /tmp/valg --out $R/gran > $R/gran.log 2>&1
echo "rc=$?" >> $R/granular.txt; grep -E "PASS|FAIL|moves|error|passed" $R/gran.log >> $R/granular.txt; el granular
mkdir -p $R/view
bash scripts/viewer/view_cost.sh "$D/rtmpm" cuda bench/snow_1m.toml 400 "$R/view" 18180 1280x720 > $R/view.txt 2>&1
grep -vE '^\{' "$R/view/view_snow_1m_client_client.log" >> $R/view.txt 2>/dev/null
python3 scripts/viewer/view_table.py "$R/view" snow_1m >> $R/view.txt 2>&1; el view
mkdir -p $R/ck; left=$(( 580 - ($(date +%s) - T0) ))
timeout $left $D/test_agreement --include-ignored --test-threads 1 cuda_agrees_with_cpu_with_ck_mpm --nocapture > $R/ck/agree.log 2>&1
echo "rc=$? (limit ${left} s)" >> $R/ck/agree.log
el agreement
{
echo "==== granular"; cat $R/granular.txt
echo "==== view"; cat $R/view.txt | tail -40
echo "==== ck agreement"; grep -E "ck-mpm|test result|rc=|FAIL|panick" $R/ck/agree.log
cat $R/times.txt
} > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude='*.ply' --exclude='*.vtu' --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
