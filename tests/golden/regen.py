"""Regenerate the golden `rblog check --json` reports of the samples (run after a deliberate
change of the engine or the analyzers, and review the diff).

    python tests/golden/regen.py
"""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

with tempfile.TemporaryDirectory() as tmp:
    for scene in sorted((REPO / "samples").glob("*.toml")):
        if scene.stem == "pile":  # slow; no golden (see tests/analyze/test_check_e2e.py SLOW_SAMPLES)
            continue
        log = Path(tmp) / f"{scene.stem}.mcap"
        subprocess.run([sys.executable, "-m", "rblog_cli.main", "run", str(scene), "--mcap", str(log)],
                       check=True, capture_output=True)
        res = subprocess.run([sys.executable, "-m", "rblog_cli.main", "check", "--json", str(log)],
                             capture_output=True, text=True)
        doc = json.loads(res.stdout)["logs"][0]
        doc["log"] = f"{scene.stem}.mcap"
        (REPO / "tests" / "golden" / f"{scene.stem}.json").write_text(json.dumps(doc, indent=1) + "\n")
        print(scene.stem, "exit", res.returncode)
