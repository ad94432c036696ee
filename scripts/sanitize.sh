#!/usr/bin/env bash
# The C++ core under AddressSanitizer + UndefinedBehaviorSanitizer (CMake option RBLOG_SANITIZE).
#
# Builds rblog into its own venv (.venv-sanitize) and build folder (build/sanitize), so the
# ordinary .venv and build/ stay untouched, then runs the engine, contact and audit tests and the
# fuzz targets' seed corpus (tests/fuzz, replayed once) in that venv. Python itself is not
# instrumented, so libasan is preloaded (it must be the first library loaded); leak detection is
# off because CPython keeps its interned objects until exit. Any ASan or UBSan report aborts the
# test process (UBSan without recovery, halt_on_error for ASan): the job passes only with no
# report.
#
#   scripts/sanitize.sh              build (incremental after the first time) and run
#   scripts/sanitize.sh -k contact   extra arguments go to pytest
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=.venv-sanitize
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV"
fi
# the build tools in the venv itself (no build isolation), so that a second run rebuilds only
# what changed: an isolated build's temporary include path would recompile every file
"$VENV/bin/pip" install -q "scikit-build-core>=0.11" "nanobind>=2.4" ninja "cmake>=3.18"
"$VENV/bin/pip" install -q --no-build-isolation -e ".[test]" -Ccmake.define.RBLOG_SANITIZE=ON \
  -Cbuild-dir=build/sanitize
LIBASAN=$(${CXX:-g++} -print-file-name=libasan.so)
LIBUBSAN=$(${CXX:-g++} -print-file-name=libubsan.so)
export ASAN_OPTIONS=detect_leaks=0:halt_on_error=1:abort_on_error=1:print_summary=1
export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1:abort_on_error=1
export RBLOG_SANITIZED=1
LD_PRELOAD="$LIBASAN:$LIBUBSAN" "$VENV/bin/python" -m pytest -q -p no:cacheprovider \
  -o faulthandler_timeout=1200 -m "not slow" \
  tests/engine tests/analyze tests/fuzz "$@"
