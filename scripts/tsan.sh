#!/usr/bin/env bash
# The C++ core under ThreadSanitizer (CMake option RBLOG_TSAN), on a threaded run of a scene.
#
# Builds rblog into its own venv (.venv-tsan) and build folder (build/tsan), RelWithDebInfo so
# that nanobind does not strip the modules (a Release build's reports have no names), then runs
# `rblog run SCENE` with RBLOG_THREADS threads (default 4) and the oversubscribed machine's
# fallback off (RBLOG_THREAD_HANDOVER=0: the stages do run on the threads), libtsan preloaded
# (Python is not instrumented). Races inside the uninstrumented libraries (CPython, numpy, the
# Rerun SDK, Arrow) are suppressed; no `called_from_lib` suppression for libpython: it would hide
# the GIL's own mutex from TSan, which then reports every object two threads touch in turn.
# Reports go to stderr; the exit code is rblog's (TSan exits 66 after a report). Not in CI: a
# run of the pile for 0.6 s takes about 2 minutes.
#
#   scripts/tsan.sh                                      the pile, 0.6 s, 4 threads
#   scripts/tsan.sh samples/mixed.toml --duration 0.2    another scene, other arguments
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=.venv-tsan
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV"
fi
"$VENV/bin/pip" install -q "scikit-build-core>=0.11" "nanobind>=2.4" ninja "cmake>=3.18"
"$VENV/bin/pip" install -q --no-build-isolation -e . -Ccmake.define.RBLOG_TSAN=ON \
  -Ccmake.build-type=RelWithDebInfo -Cbuild-dir=build/tsan
SUPP=$(mktemp)
trap 'rm -f "$SUPP" "$OUT".rrd "$OUT".mcap' EXIT
printf 'race:libpython*\nrace:_multiarray_umath*\nrace:libopenblas*\nrace:rerun*\nrace:libarrow*\n' \
  > "$SUPP"
OUT=$(mktemp -u)
SCENE=${1:-samples/pile.toml}
shift || true
ARGS=("$@")
[ ${#ARGS[@]} -gt 0 ] || ARGS=(--duration 0.6)
LIBTSAN=$(${CXX:-g++} -print-file-name=libtsan.so)
RBLOG_THREADS=${RBLOG_THREADS:-4} RBLOG_THREAD_HANDOVER=0 \
  TSAN_OPTIONS="suppressions=$SUPP report_signal_unsafe=0 ${TSAN_OPTIONS:-}" \
  LD_PRELOAD="$LIBTSAN" "$VENV/bin/rblog" run "$SCENE" --rrd "$OUT.rrd" --mcap "$OUT.mcap" \
  "${ARGS[@]}"
