#!/usr/bin/env bash
# The browser path of `rtmpm view` in a real browser: Debian's headless Chromium driven by
# Playwright (its Python package from PyPI; no browser is downloaded), against the CLI's
# `rtmpm view scenes/sandbox.toml --serve` on the CPU backend. Installs what it needs:
# chromium and chromium-driver (apt, when /usr/bin/chromium is missing), playwright (pip, into
# target/ci-tools/playwright). Writes the page's screenshot to target/viewer-screenshot.png.
set -euo pipefail
cd "$(dirname "$0")/.."
rtmpm=${RTMPM:-target/debug/rtmpm}
[ -n "${RTMPM:-}" ] || cargo build --quiet -p rtmpm
if [ ! -x /usr/bin/chromium ]; then
  sudo_=""
  [ "$(id -u)" -eq 0 ] || sudo_="sudo"
  $sudo_ apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -qq --no-install-recommends \
    chromium chromium-driver >/dev/null
fi
tools="$PWD/target/ci-tools/playwright"
if ! PYTHONPATH="$tools" python3 -c "import playwright" 2>/dev/null; then
  python3 -m pip install --quiet --disable-pip-version-check --target "$tools" "playwright==1.65.2"
fi
PYTHONPATH="$tools${PYTHONPATH:+:$PYTHONPATH}" python3 scripts/viewer/browser_test.py \
  --rtmpm "$rtmpm" --screenshot target/viewer-screenshot.png
