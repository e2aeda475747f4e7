#!/usr/bin/env python3
"""Kill soak: SIGKILL a calibration job (or `calib loop`) at random moments,
resume it each time, and check that it ends with the history of an
uninterrupted run.

    scripts/kill-soak.py [--calib build/apps/calib] [--kills 50] [--seed 1]
                         [--evaluations 600] [--work DIR]
    scripts/kill-soak.py --loop [--calib ...] [--kills 50] [--seed 1] [--work DIR]

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

With --loop the soak is over `calib loop` on examples/push_centre, held out
examples/push_offset, at a small budget (36 evaluations for the base
model, 18 for an effect, one effect tried whatever its confidence, 2
threads). Each round starts `calib loop` (then `calib loop --resume`), waits
until its store has recorded a new evaluation, waits a random 0..1 s more
(so that kills land in the searches, the held-out scoring, the residual
analysis and the report alike) and sends SIGKILL. After the last kill a
resume finishes the loop; its report's numbers (everything but times, the
command line and overlay paths) and every stored evaluation of every job
must equal the reference loop's.
"""

import argparse
import json
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

EVALUATION_COLUMNS = (
    "e.id, e.x_json, e.parameters_json, e.status, e.score, e.mean_iou, e.iou_min, e.iou_max, "
    "e.failure_frame, e.reason, e.attempt, e.detail_json")


def stored_rows(db, query):
    """The rows of `query` on the store `db`; none while it does not exist yet."""
    if not os.path.exists(db):
        return []
    with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=30) as con:
        try:
            return con.execute(query).fetchall()
        except sqlite3.OperationalError:  # being created
            return []


def history(db):
    """Every evaluation of the soak job, by id."""
    return stored_rows(db, f"SELECT {EVALUATION_COLUMNS} FROM evaluations e JOIN jobs j "
                           "ON j.id = e.job_id WHERE j.name = 'soak' ORDER BY e.id")


def loop_history(out):
    """Every evaluation of every job in a loop's store, by job name and id."""
    return stored_rows(os.path.join(out, "store.sqlite"),
                       f"SELECT j.name, {EVALUATION_COLUMNS} FROM evaluations e JOIN jobs j "
                       "ON j.id = e.job_id ORDER BY j.name, e.id")


def loop_numbers(out):
    """report.json without what depends on the clock or the folder."""
    path = os.path.join(out, "report.json")
    if not os.path.exists(path):
        return None
    with open(path) as f:
        report = json.load(f)
    for key in ("run_time_s", "command", "overlays"):
        report.pop(key, None)
    for stage in report.get("stages", []):
        stage.pop("calibration_time_s", None)
    return report


def kill_rounds(args, command, progress, max_delay):
    """Start `command(round)` again and again; each time wait until
    `progress()` grows, a random 0..max_delay s more, and SIGKILL it. Stops
    after args.kills kills, or when a round finishes by itself (exit 0) or
    fails. Returns (kills, invocations, finished, failures)."""
    rng = random.Random(args.seed)
    kills = invocations = 0
    finished = False
    failures = []
    while kills < args.kills and not finished:
        before = progress()
        child = subprocess.Popen(command(invocations), stdout=args.log, stderr=args.log)
        invocations += 1
        while child.poll() is None and progress() <= before:
            time.sleep(0.01)
        time.sleep(rng.uniform(0.0, max_delay))
        if child.poll() is None:
            child.send_signal(signal.SIGKILL)
        code = child.wait()
        if code == -signal.SIGKILL:
            kills += 1
        elif code == 0:
            finished = True
        else:
            failures.append(f"invocation {invocations} exited {code}")
            break
    return kills, invocations, finished, failures


def loop_soak(args):
    work = args.work or tempfile.mkdtemp(prefix="calib-loop-kill-soak-")
    os.makedirs(work, exist_ok=True)
    log = open(os.path.join(work, "calib.log"), "w")
    examples = os.path.join(REPO, "examples")

    def calib(out, resume):
        return ([args.calib, "loop", "--train", os.path.join(examples, "push_centre"),
                 "--holdout", os.path.join(examples, "push_offset"), "--out", out,
                 "--budget", "36", "--effect-budget", "18", "--max-effects", "1", "--tries", "1",
                 "--min-confidence", "0", "--equally-good-fits", "4", "--overlays", "0",
                 "--threads", "2", "--no-html", "--quiet",
                 "--cache-dir", os.path.join(work, "cache")] + (["--resume"] if resume else []))

    start = time.time()
    reference_out = os.path.join(work, "reference")
    subprocess.run(calib(reference_out, False), check=True, stdout=log, stderr=log)
    reference = (loop_numbers(reference_out), loop_history(reference_out))
    reference_s = time.time() - start

    out = os.path.join(work, "soak")
    args.log = log
    kills, invocations, finished, failures = kill_rounds(
        args, lambda round: calib(out, round > 0), lambda: len(loop_history(out)), 1.0)
    if not finished and not failures:
        invocations += 1
        code = subprocess.run(calib(out, True), stdout=log, stderr=log).returncode
        if code != 0:
            failures.append(f"the last resume exited {code}")
    soak = (loop_numbers(out), loop_history(out))
    same_numbers = soak[0] == reference[0]
    same_history = soak[1] == reference[1]

    print(f"work folder: {work} (calib's output in calib.log)")
    print(f"reference loop: {len(reference[1])} evaluations in {reference_s:.1f} s")
    print(f"kills: {kills} SIGKILLs over {invocations} invocations; "
          f"{'the loop finished before the last kill' if finished else 'then one resume to the end'}")
    print(f"report after the kills: {'identical' if same_numbers else 'DIFFERENT'} numbers; "
          f"store: {len(soak[1])} evaluations, "
          f"{'identical to the reference' if same_history else 'DIFFERENT from the reference'}")
    for f in failures:
        print(f"failure: {f}")
    print(f"total: {time.time() - start:.1f} s")
    return 0 if same_numbers and same_history and not failures and kills >= args.kills else 1


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--calib", default=os.path.join(REPO, "build", "apps", "calib"))
    parser.add_argument("--kills", type=int, default=50)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--evaluations", type=int, default=600)
    parser.add_argument("--loop", action="store_true", help="soak `calib loop` instead of a job")
    parser.add_argument("--work", default=None, help="folder for the stores (default: a new temporary one)")
    args = parser.parse_args()
    if args.loop:
        return loop_soak(args)

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

    db = os.path.join(work, "soak.sqlite")
    args.log = log
    kills, invocations, finished, failures = kill_rounds(
        args, lambda round: calib("resume" if os.path.exists(db) else "run", db),
        lambda: len(history(db)), 0.1)
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
