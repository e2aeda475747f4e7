#!/usr/bin/env python3
"""Helper of scripts/compare-outputs.sh (standard library, plus PyYAML for
reading a YAML job spec): writes the copy of a job spec the comparison runs,
lists a results store's jobs, turns the raw exports of `calib results --json`,
`calib best` and `calib loop`'s report.json into canonical files (timing
fields removed, revision-specific paths replaced), and compares two such
canonical folders.

  canonical-outputs.py make-spec SPEC OUT_SPEC --store DB --out-dir DIR
  canonical-outputs.py store-jobs DB
  canonical-outputs.py canonical-job RAW_DIR CANON_DIR
  canonical-outputs.py canonical-loop RAW_DIR CANON_DIR
  canonical-outputs.py compare LABEL OLD_CANON NEW_CANON

Canonical files are JSON with sorted keys; an evaluation history is one
evaluation per line (history*.jsonl), so that a plain `diff` of two canonical
folders is readable too. Doubles are written by Python's repr, which reads
back to the same double: the comparison is exact.
"""

import json
import os
import re
import sqlite3
import sys

# Fields that hold wall-clock times, durations or who ran what: they differ
# from run to run and are not behaviour. Removed wherever they occur.
TIMING_KEYS = {
    "eval_time_s",          # store / results export: an evaluation's duration
    "worker",               # store: host / thread that evaluated it
    "recorded_unix_s",      # store: when it was recorded
    "created_unix_s",       # store: job created
    "updated_unix_s",       # store: job updated
    "mean_eval_time_s",     # results export summary
    "total_eval_time_s",    # results export summary
    "first_recorded_unix_s",
    "last_recorded_unix_s",
    "run_time_s",           # loop report.json: the loop's run time
    "calibration_time_s",   # loop report.json: each stage's calibration time
}
# Keys removed only inside the results export's "summary": how many
# checkpoints are kept depends on checkpoint.every_seconds (wall clock).
SUMMARY_TIMING_KEYS = {"checkpoints"}


def load_json(path):
    with open(path) as f:
        return json.load(f)


def write_json(path, doc):
    with open(path, "w") as f:
        json.dump(doc, f, sort_keys=True, indent=1)
        f.write("\n")


def write_jsonl(path, rows):
    with open(path, "w") as f:
        for row in rows:
            f.write(json.dumps(row, sort_keys=True) + "\n")


def strip_timing(doc):
    """Copy of doc without the timing keys (at any depth)."""
    if isinstance(doc, dict):
        out = {}
        for k, v in doc.items():
            if k in TIMING_KEYS or k.endswith("_unix_s"):
                continue
            out[k] = strip_timing(v)
        return out
    if isinstance(doc, list):
        return [strip_timing(v) for v in doc]
    return doc


def replacer(paths):
    """A function replacing the revision-specific strings recorded in
    paths.json (the calib binary, the output folder, the commit hash) by
    placeholders in every string of a document."""
    pairs = []
    if paths.get("calib"):
        pairs.append((paths["calib"], "calib"))
    if paths.get("out"):
        pairs.append((paths["out"], "<OUT>"))
    if paths.get("rev"):
        pairs.append((paths["rev"], "<REV>"))

    def fix(doc):
        if isinstance(doc, dict):
            return {fix(k): fix(v) for k, v in doc.items()}
        if isinstance(doc, list):
            return [fix(v) for v in doc]
        if isinstance(doc, str):
            for old, new in pairs:
                doc = doc.replace(old, new)
            return doc
        return doc

    return fix


# ---------------------------------------------------------------------------
# make-spec


def yaml_loader():
    import yaml  # Debian: python3-yaml

    class Loader(yaml.SafeLoader):
        pass

    # YAML 1.2 floats (as yaml-cpp reads them): PyYAML's YAML 1.1 resolver
    # reads 1e-3 as a string.
    Loader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                    |\.[0-9_]+(?:[eE][-+][0-9]+)?
                    |[-+]?\.(?:inf|Inf|INF)
                    |\.(?:nan|NaN|NAN))$""", re.X),
        list("-+0123456789."))
    return Loader


def make_spec(args):
    spec_path, out_spec = args[0], args[1]
    opts = dict(zip(args[2::2], args[3::2]))
    import yaml
    with open(spec_path) as f:
        spec = yaml.load(f, Loader=yaml_loader())
    base = os.path.dirname(os.path.abspath(spec_path))
    for key in ("train", "holdout"):
        if key in spec:
            spec[key] = [os.path.normpath(os.path.join(base, p)) for p in spec[key]]
    spec["results"] = {"store": opts["--store"], "out_dir": opts["--out-dir"]}
    # A wall-time limit would make the history depend on the machine's speed.
    if isinstance(spec.get("budget"), dict):
        spec["budget"].pop("wall_time_s", None)
    write_json(out_spec, spec)


# ---------------------------------------------------------------------------
# store-jobs


def store_jobs(args):
    db = sqlite3.connect("file:{}?mode=ro".format(args[0]), uri=True)
    for (name,) in db.execute("SELECT name FROM jobs ORDER BY id"):
        print(name)


# ---------------------------------------------------------------------------
# canonical forms


def canonical_results(raw_json, fix):
    """`calib results --json` export -> (job document, history rows)."""
    doc = fix(strip_timing(load_json(raw_json)))
    history = doc.pop("evaluations", [])
    summary = doc.get("summary")
    if isinstance(summary, dict):
        for k in SUMMARY_TIMING_KEYS:
            summary.pop(k, None)
    job = doc.get("job")
    if isinstance(job, dict):
        job.pop("id", None)  # the store's row id: the order jobs were created in
    return doc, history


def canonical_job(args):
    raw, canon = args
    os.makedirs(canon, exist_ok=True)
    fix = replacer(load_json(os.path.join(raw, "paths.json")))
    doc, history = canonical_results(os.path.join(raw, "results.json"), fix)
    write_jsonl(os.path.join(canon, "history.jsonl"), history)
    write_json(os.path.join(canon, "job.json"), doc)
    write_json(os.path.join(canon, "best.json"), load_json(os.path.join(raw, "best.json")))


def canonical_loop(args):
    raw, canon = args
    os.makedirs(canon, exist_ok=True)
    fix = replacer(load_json(os.path.join(raw, "paths.json")))
    report = fix(strip_timing(load_json(os.path.join(raw, "out", "report.json"))))
    write_json(os.path.join(canon, "report.json"), report)
    jobs = [line.strip() for line in open(os.path.join(raw, "store-jobs.txt")) if line.strip()]
    write_json(os.path.join(canon, "store-jobs.json"), jobs)
    for i, name in enumerate(jobs):
        doc, history = canonical_results(os.path.join(raw, "store", name + ".json"), fix)
        write_jsonl(os.path.join(canon, "history-{:02d}-{}.jsonl".format(i, name)), history)
        write_json(os.path.join(canon, "job-{:02d}-{}.json".format(i, name)), doc)


# ---------------------------------------------------------------------------
# compare


def differences(old, new, path, out, limit):
    """Appends 'path: old -> new' lines for the first `limit` differences."""
    if len(out) >= limit:
        return
    if type(old) is not type(new) and not (
            isinstance(old, (int, float)) and isinstance(new, (int, float))
            and not isinstance(old, bool) and not isinstance(new, bool)):
        out.append("{}: {} -> {}".format(path, short(old), short(new)))
        return
    if isinstance(old, dict):
        for k in list(old) + [k for k in new if k not in old]:  # files are key-sorted
            p = "{}.{}".format(path, k) if path else k
            if k not in old:
                out.append("{}: only in NEW ({})".format(p, short(new[k])))
            elif k not in new:
                out.append("{}: only in OLD ({})".format(p, short(old[k])))
            else:
                differences(old[k], new[k], p, out, limit)
            if len(out) >= limit:
                return
    elif isinstance(old, list):
        for i in range(min(len(old), len(new))):
            differences(old[i], new[i], "{}[{}]".format(path, i), out, limit)
            if len(out) >= limit:
                return
        if len(old) != len(new):
            out.append("{}: {} items -> {} items".format(path, len(old), len(new)))
    elif old != new or repr(old) != repr(new):
        out.append("{}: {} -> {}".format(path, short(old), short(new)))


def short(v):
    text = json.dumps(v, sort_keys=True)
    return text if len(text) <= 100 else text[:97] + "..."


def read_canonical(path):
    if path.endswith(".jsonl"):
        rows = [json.loads(line) for line in open(path) if line.strip()]
        # Label each evaluation by its id in the difference paths.
        return {"evaluation {}".format(r.get("id", i)): r for i, r in enumerate(rows)}, rows
    doc = load_json(path)
    return doc, doc


def describe(canon):
    """A few words on what a canonical folder holds (for 'identical' lines)."""
    words = []
    if os.path.exists(os.path.join(canon, "history.jsonl")):
        rows = read_canonical(os.path.join(canon, "history.jsonl"))[1]
        best = load_json(os.path.join(canon, "job.json")).get("summary", {}).get("best") or {}
        words.append("{} evaluations, best #{} score {}".format(
            len(rows), best.get("id"), best.get("score")))
    if os.path.exists(os.path.join(canon, "report.json")):
        report = load_json(os.path.join(canon, "report.json"))
        stages = ["{}:{}".format(s.get("effect_tried") or "base", s.get("decision"))
                  for s in report.get("stages", [])]
        jobs = load_json(os.path.join(canon, "store-jobs.json"))
        evals = sum(len(read_canonical(os.path.join(canon, f))[1])
                    for f in os.listdir(canon) if f.startswith("history-"))
        words.append("stages {}; kept [{}]; {} store jobs, {} evaluations".format(
            " ".join(stages), ", ".join(report.get("effects_kept", [])), len(jobs), evals))
    return "; ".join(words)


def compare(args):
    label, old_dir, new_dir = args
    files = sorted(set(os.listdir(old_dir)) | set(os.listdir(new_dir)))
    lines = []
    for name in files:
        a, b = os.path.join(old_dir, name), os.path.join(new_dir, name)
        if not os.path.exists(a) or not os.path.exists(b):
            lines.append("  {}: only in {}".format(name, "NEW" if not os.path.exists(a) else "OLD"))
            continue
        old, old_rows = read_canonical(a)
        new, new_rows = read_canonical(b)
        if json.dumps(old_rows, sort_keys=True) == json.dumps(new_rows, sort_keys=True):
            continue  # exact: repr of every double, -0.0 and 1.0 vs 1 included
        found = []
        if name.endswith(".jsonl") and len(old_rows) != len(new_rows):
            found.append("{} evaluations -> {}".format(len(old_rows), len(new_rows)))
        differences(old, new, "", found, 5)
        lines.append("  {}: differs (OLD -> NEW; first differences)".format(name))
        lines.extend("    " + d for d in found[:5])
    if lines:
        print("{}: DIFFERENT".format(label))
        print("\n".join(lines))
        return 1
    print("{}: identical ({})".format(label, describe(new_dir)))
    return 0


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    command, args = sys.argv[1], sys.argv[2:]
    if command == "make-spec":
        make_spec(args)
    elif command == "store-jobs":
        store_jobs(args)
    elif command == "canonical-job":
        canonical_job(args)
    elif command == "canonical-loop":
        canonical_loop(args)
    elif command == "compare":
        sys.exit(compare(args))
    else:
        sys.exit("unknown command {}\n{}".format(command, __doc__))


if __name__ == "__main__":
    main()
