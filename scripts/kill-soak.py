#!/usr/bin/env python3
"""Kill soak: SIGKILL a calibration job at random moments, resume it each
time, and check that it ends with the history of an uninterrupted run.

    scripts/kill-soak.py [--calib build/apps/calib] [--kills 50] [--seed 1]
                         [--evaluations 600] [--work DIR]

The job is examples/jobs/push_centre_cmaes.yaml made small: CMA-ES over the
base model on examples/push_centre only, 40 px mesh edges, 4 substeps,
generations of 4, 2 threads, a checkpoint every 4 evaluations. Each round
starts `calib run` (then `calib resume`), waits until it has recorded
something new, waits a random 0..0.1 s more and sends SIGKILL; the next
resume takes over the killed process's lock at once. After the last kill a
resume finishes the job, and every evaluation (id, point, parameters,
status, score, IoU summary, failure, attempts, detail) must equal the
reference run's. Exit status 0 when it does and every kill landed; the
figures are printed at the end (docs/reliability.md keeps them).
"""

import argparse
import os
import random
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time

import yaml  # python3-yaml (scripts/install-deps.sh)

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

EXAMPLE = os.path.join(REPO, "examples", "jobs", "push_centre_cmaes.yaml")


def soak_spec(evaluations):
    """The example job made small: the train recording only, coarse mesh, few
    substeps, generations of 4, a checkpoint every 4 evaluations."""
    with open(EXAMPLE) as f:
        spec = yaml.safe_load(f)
    spec["name"] = "soak"
    spec["train"] = [os.path.join(REPO, "examples", "push_centre")]
    del spec["holdout"], spec["results"]
    spec["model"].update({"substeps": 4, "mesh": {"edge_length_px": 40}})
    spec["optimizer"]["settings"]["population"] = 4
    spec["budget"] = {"evaluations": evaluations}
    spec.update({"seed": 3, "threads": 2,
                 "checkpoint": {"every_evaluations": 4, "every_seconds": 0}})
    return yaml.safe_dump(spec, sort_keys=False)

HISTORY = (
    "SELECT e.id, e.x_json, e.parameters_json, e.status, e.score, e.mean_iou, e.iou_min, "
    "e.iou_max, e.failure_frame, e.reason, e.attempt, e.detail_json FROM evaluations e "
    "JOIN jobs j ON j.id = e.job_id WHERE j.name = 'soak' ORDER BY e.id")


def history(db):
    if not os.path.exists(db):
        return []
    with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=30) as con:
        try:
            return con.execute(HISTORY).fetchall()
        except sqlite3.OperationalError:  # being created
            return []


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--calib", default=os.path.join(REPO, "build", "apps", "calib"))
    parser.add_argument("--kills", type=int, default=50)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--evaluations", type=int, default=600)
    parser.add_argument("--work", default=None, help="folder for the stores (default: a new temporary one)")
    args = parser.parse_args()

    work = args.work or tempfile.mkdtemp(prefix="calib-kill-soak-")
    os.makedirs(work, exist_ok=True)
    spec = os.path.join(work, "soak.yaml")
    with open(spec, "w") as f:
        f.write(soak_spec(args.evaluations))
    common = ["--no-report", "--progress", "none", "--cache-dir", os.path.join(work, "cache")]
    log = open(os.path.join(work, "calib.log"), "w")

    def calib(verb, db):
        return [args.calib, verb, spec, "--store", db] + common

    start = time.time()
    reference_db = os.path.join(work, "reference.sqlite")
    subprocess.run(calib("run", reference_db), check=True, stdout=log, stderr=log)
    reference = history(reference_db)
    reference_s = time.time() - start

    rng = random.Random(args.seed)
    db = os.path.join(work, "soak.sqlite")
    kills = invocations = 0
    finished = False
    failures = []
    while kills < args.kills and not finished:
        before = len(history(db))
        verb = "resume" if before > 0 or os.path.exists(db) else "run"
        child = subprocess.Popen(calib(verb, db), stdout=log, stderr=log)
        invocations += 1
        while child.poll() is None and len(history(db)) <= before:
            time.sleep(0.01)
        time.sleep(rng.uniform(0.0, 0.1))
        if child.poll() is None:
            child.send_signal(signal.SIGKILL)
        code = child.wait()
        if code == -signal.SIGKILL:
            kills += 1
        elif code == 0:
            finished = True
        else:
            failures.append(f"{verb} (invocation {invocations}) exited {code}")
            break
    if not finished and not failures:
        invocations += 1
        code = subprocess.run(calib("resume", db), stdout=log, stderr=log).returncode
        if code != 0:
            failures.append(f"the last resume exited {code}")
    soak = history(db)
    same = soak == reference

    print(f"work folder: {work} (calib's output in calib.log)")
    print(f"reference run: {len(reference)} evaluations in {reference_s:.1f} s")
    print(f"kills: {kills} SIGKILLs over {invocations} invocations; "
          f"{'the job finished before the last kill' if finished else 'then one resume to the end'}")
    print(f"history after the kills: {len(soak)} evaluations, "
          f"{'identical to the reference' if same else 'DIFFERENT from the reference'}")
    for f in failures:
        print(f"failure: {f}")
    print(f"total: {time.time() - start:.1f} s")
    return 0 if same and not failures and kills >= args.kills else 1


if __name__ == "__main__":
    sys.exit(main())
