"""One command of the tool, timed, for the benchmarks that run the pipeline as a user does."""
from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def timed_command(args: list, log: Path) -> dict:
    """``fluidnexus ARGS`` under /usr/bin/time -v in a fresh process, its output appended to ``log``: seconds and
    peak resident memory (MiB). RuntimeError naming the log when the command fails."""
    cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "fluidnexus_cli", *map(str, args)]
    tic = time.time()
    with open(log, "a") as fh:
        fh.write("$ fluidnexus " + " ".join(map(str, args)) + "\n")
        fh.flush()
        proc = subprocess.run(cmd, stdout=fh, stderr=subprocess.STDOUT, cwd=ROOT)
    peak = re.findall(r"Maximum resident set size \(kbytes\): (\d+)", log.read_text())
    if proc.returncode != 0:
        raise RuntimeError(f"fluidnexus {args[0]} failed (exit {proc.returncode}); see {log}")
    return {"seconds": round(time.time() - tic, 1), "peak_mib": round(int(peak[-1]) / 1024, 1)}
