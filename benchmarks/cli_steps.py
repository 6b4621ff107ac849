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


def pinf_pipeline(data: Path, work: Path, inputs: list, held_out: list, frames: str, recon: list) -> dict:
    """A PINF scene through the tool as a user runs it, into ``work``: ``calibrate --from-pinf`` (``inputs`` in,
    ``held_out`` as ground truth), ``background``, ``recon`` (``recon``: its options after the scene; a killed run
    continues with ``--resume``), ``eval --json work/eval.json``, ``render --compare`` of the held-out views into
    work/videos. Steps whose output exists are skipped; returns their timings (``timed_command``)."""
    log, scene, runs = work / "log.txt", work / "scene", work / "run"
    steps = {}
    if not (scene / "scene.json").exists():
        steps["calibrate"] = timed_command(["calibrate", "--from-pinf", data / "info.json", "--input", ",".join(inputs),
                                            "--ground-truth", ",".join(held_out), "--out", scene], log)
    if not (scene / "backgrounds").exists():
        steps["background"] = timed_command(["background", scene], log)
    resume = ["--resume"] if (runs / "config.json").exists() else []
    steps["recon"] = timed_command(["recon", scene, "--out", runs, "--frames", frames, "--arch", "cpu", *resume,
                                    *recon], log)
    steps["eval"] = timed_command(["eval", runs, "--json", work / "eval.json", "--arch", "cpu"], log)
    steps["render"] = timed_command(["render", runs, "--out", work / "videos", "--views", ",".join(held_out),
                                     "--compare", "--arch", "cpu"], log)
    return steps
