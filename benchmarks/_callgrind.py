"""Instruction counts of a worker process under valgrind's callgrind, for the benchmarks whose
``--instructions`` mode CI uses as a guard (bench_check.py, bench_adapters.py): a shared machine's
load does not move them as it moves CPU time."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

#: one thread for every BLAS and OpenMP pool, a fixed hash seed, the editable build quiet
ENV = {"SKBUILD_EDITABLE_VERBOSE": "0", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
       "PYTHONHASHSEED": "0"}


def total_instructions(cmd: list[str], out: Path, who: str, cwd: str | None = None) -> int:
    """The instructions callgrind counts over the whole process ``cmd`` (its output file ``out``);
    exits naming ``who`` when the process fails or callgrind writes no total."""
    run = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", *cmd],
                         cwd=cwd, env={**os.environ, **ENV}, capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"{who} failed:\n{run.stderr[-2000:]}")
    for line in out.read_text().splitlines():
        if line.startswith(("summary:", "totals:")):
            return int(line.split()[1])
    sys.exit(f"{who}: no totals in {out}")
