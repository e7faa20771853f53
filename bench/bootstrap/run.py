"""The bootstrap's re-run is a no-op (moved out of the suite, issue 19: it ran the installer with a
10 s wall limit inside pytest). The first run catches up with any edit; the second must do nothing.

    python bench/bootstrap/run.py        # prints and writes bench/results/bootstrap.json

Exit 1 if the second run installs or builds anything, or fails.
"""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def main() -> int:
    cmd = ["bash", str(REPO / "scripts" / "bootstrap.sh")]
    first = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
    t0 = time.monotonic()
    second = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    elapsed = time.monotonic() - t0
    noop = second.returncode == 0 and "installing" not in second.stderr and "building" not in second.stderr
    out = {"command": "python bench/bootstrap/run.py", "first_rc": first.returncode,
           "second_rc": second.returncode, "second_seconds": round(elapsed, 2), "second_is_noop": noop}
    (REPO / "bench" / "results" / "bootstrap.json").write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))
    return 0 if noop and first.returncode == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
