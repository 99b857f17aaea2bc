#!/usr/bin/env bash
# Install Debian's headless-capable Chromium (used by tests/ros/test_analyze.py to render the
# bb2-analyze HTML report).  Idempotent; never fails the caller: exits 0 and says why when it cannot.
set -u
if command -v chromium >/dev/null 2>&1; then
  echo "[install_chromium] chromium already installed: $(command -v chromium)"
  exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
  echo "[install_chromium] apt-get not available: cannot install chromium (the report screenshot test will skip)"
  exit 0
fi
SUDO=""
if [ "$(id -u)" != "0" ]; then
  if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    SUDO="sudo -n"
  else
    echo "[install_chromium] not root and no passwordless sudo: cannot install chromium (the screenshot test will skip)"
    exit 0
  fi
fi
export DEBIAN_FRONTEND=noninteractive
if ! $SUDO apt-get update -q >/dev/null 2>&1; then
  echo "[install_chromium] apt-get update failed (offline or no repository access): chromium not installed"
  exit 0
fi
if ! $SUDO apt-get install -y -q --no-install-recommends chromium >/dev/null 2>&1; then
  echo "[install_chromium] apt-get install chromium failed: chromium not installed (the screenshot test will skip)"
  exit 0
fi
echo "[install_chromium] installed $(command -v chromium || echo '(chromium still not on PATH)')"
exit 0
