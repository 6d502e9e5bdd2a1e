#!/usr/bin/env bash
# Device call of the cbatch helper: unpack the carried binaries and kernel cache, run the batch suite.
set -uo pipefail
mkdir -p /tmp/cb && tar xJf .device-cbatch/d.tar.xz -C /tmp/cb || exit 1
export RTMPM_CACHE_DIR=/tmp/cb/kcache D=/tmp/cb
ls /tmp/cb/kcache | head
TEST_TIMEOUT=${TEST_TIMEOUT:-200} bash /tmp/cb/run.sh batch
