#!/usr/bin/env bash
# BB2 Sim: the two commands that do everything on a fresh clone.
#   bash run.sh main    set up .venv (first time) and run the main job
#   bash run.sh test    set up .venv (first time) and run the whole test suite
# Other sub-commands: setup (venv only), lint (ruff check .), bench (benchmarks/), shell (a shell with the venv active).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
cd "$here"
venv="${BB2_VENV:-$here/.venv}"

setup() {
  local stamp="$venv/.bb2-setup-stamp"
  local want
  want="$(cat requirements.txt pyproject.toml bb2_ros_ws/src/*/setup.py bb2_ros_ws/install_into_venv.py | sha256sum | cut -d' ' -f1)"
  if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then return 0; fi
  echo "[run.sh] creating/updating the virtual environment in $venv" >&2
  [ -x "$venv/bin/python" ] || python3 -m venv "$venv"
  "$venv/bin/python" -m pip install -q --upgrade pip >/dev/null 2>&1 || true
  "$venv/bin/python" -m pip install -q -r requirements.txt 2>&1 | grep -v "is ignored: it is neither" || true
  "$venv/bin/python" -m pip install -q --no-deps --no-build-isolation -e . 2>&1 | grep -v "is ignored: it is neither" || true
  "$venv/bin/python" bb2_ros_ws/install_into_venv.py -q   # lib/<pkg>/<exe> + ament index, as `ros2 run` expects
  "$venv/bin/python" -c "import numpy, scipy, trimesh, mcap, rclpy, bb2_sim" || { echo "[run.sh] setup failed" >&2; exit 1; }
  echo "$want" > "$stamp"
}

activate() {
  export PATH="$venv/bin:$PATH"
  export AMENT_PREFIX_PATH="$venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
  export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
  export MPLBACKEND=Agg
  export PYTHONDONTWRITEBYTECODE=1
}

cmd="${1:-}"; shift || true
case "$cmd" in
  setup) setup ;;
  main)  setup; activate; exec python -m bb2_tools.main_job "$@" ;;
  test)  setup; bash tools/install_chromium.sh >&2 || true; activate
         echo "[run.sh] ruff check ." >&2; ruff check -q . || { echo "[run.sh] ruff check failed" >&2; exit 1; }
         exec python -m pytest -q -p no:cacheprovider -n "${BB2_TEST_WORKERS:-2}" --dist loadfile --no-loadscope-reorder --durations=40 tests "$@" ;;
  lint)  setup; activate; exec ruff check . ;;
  bench) setup; activate; for b in benchmarks/*.py; do echo "== $b"; python "$b"; done ;;
  shell) setup; activate; exec "${SHELL:-bash}" ;;
  *) echo "usage: bash run.sh main|test|setup|lint|bench|shell" >&2; exit 2 ;;
esac
