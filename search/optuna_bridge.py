#!/usr/bin/python3
"""Optuna's samplers as a calib external optimiser (search/README.md,
docs/compare.md "External optimisers"): ask/tell as JSON lines on stdin and
stdout. Run by Debian's /usr/bin/python3 with python3-optuna (and
python3-cmaes for the CMA-ES sampler), e.g. in a spec:

  optimizer:
    name: external
    settings:
      command: [/usr/bin/python3, search/optuna_bridge.py]
      options: {sampler: tpe}      # or cmaes

Options: sampler (tpe | cmaes, default tpe); n_startup_trials (TPE, default
Optuna's 10); failed (worst | fail, default worst): what the study is told
of an evaluation that failed (value null). "worst": the worst value any
trial has finished with so far, as calib's own optimisers rank a failure
worse than any finished evaluation, so that the sampler learns to avoid
where simulations fail; "fail": Optuna's FAIL state, which its samplers
leave out of their models (they keep proposing there). Before any trial has
finished a failure is told as FAIL either way. The study minimises over the
box given in "start", one float parameter per coordinate, seeded with the
job's seed. "save" returns the whole in-memory study pickled (its trials,
the sampler and the sampler's random state, base64), so a restored bridge
proposes exactly what this one would have.
"""

import base64
import json
import pickle
import sys

import optuna


def reply(obj):
    sys.stdout.write(json.dumps(obj) + "\n")
    sys.stdout.flush()


class Bridge:
    def __init__(self):
        self.study = None
        self.distributions = None
        self.pending = []  # trial numbers asked and not yet told, ask order
        self.failed_as_worst = True
        self.worst = None  # the worst value a trial finished with (failures told as it excluded)

    def start(self, msg):
        options = msg.get("options") or {}
        unknown = set(options) - {"sampler", "n_startup_trials", "failed"}
        if unknown:
            raise ValueError("unknown options: %s (known: sampler, n_startup_trials, failed)" % sorted(unknown))
        failed = options.get("failed", "worst")
        if failed not in ("worst", "fail"):
            raise ValueError("failed '%s' is unknown; worst or fail" % failed)
        self.failed_as_worst = failed == "worst"
        name = options.get("sampler", "tpe")
        seed = int(msg["seed"]) % (2 ** 32)
        if name == "tpe":
            kwargs = {"seed": seed}
            if "n_startup_trials" in options:
                kwargs["n_startup_trials"] = int(options["n_startup_trials"])
            sampler = optuna.samplers.TPESampler(**kwargs)
        elif name == "cmaes":
            sampler = optuna.samplers.CmaEsSampler(seed=seed)
        else:
            raise ValueError("sampler '%s' is unknown; tpe or cmaes" % name)
        self.study = optuna.create_study(sampler=sampler, direction="minimize")
        self.distributions = {
            "x%d" % i: optuna.distributions.FloatDistribution(lo, hi)
            for i, (lo, hi) in enumerate(zip(msg["lower"], msg["upper"]))
        }
        return {"ok": True}

    def ask(self, msg):
        points = []
        for _ in range(int(msg["count"])):
            trial = self.study.ask(self.distributions)
            self.pending.append(trial.number)
            points.append([trial.params["x%d" % i] for i in range(len(self.distributions))])
        return {"points": points}

    def tell(self, msg):
        results = msg["results"]
        if len(results) != len(self.pending):
            raise ValueError("told %d results for %d points asked" % (len(results), len(self.pending)))
        # The finished first, so that a failure in the batch is told the
        # worst value including theirs; then the failures, in ask order.
        for number, result in zip(self.pending, results):
            if result["value"] is not None:
                value = float(result["value"])
                self.study.tell(number, value)
                self.worst = value if self.worst is None else max(self.worst, value)
        for number, result in zip(self.pending, results):
            if result["value"] is None:
                if self.failed_as_worst and self.worst is not None:
                    self.study.tell(number, self.worst)
                else:
                    self.study.tell(number, state=optuna.trial.TrialState.FAIL)
        self.pending = []
        return {"ok": True}

    def save(self, msg):
        blob = pickle.dumps((self.study, self.distributions, self.pending, self.failed_as_worst, self.worst))
        return {"state": {"pickle": base64.b64encode(blob).decode("ascii"), "optuna": optuna.__version__}}

    def restore(self, msg):
        state = msg["state"]
        if state.get("optuna") != optuna.__version__:
            raise ValueError("state saved by Optuna %s, this is %s" % (state.get("optuna"), optuna.__version__))
        (self.study, self.distributions, self.pending, self.failed_as_worst,
         self.worst) = pickle.loads(base64.b64decode(state["pickle"]))
        return {"ok": True}


def main():
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    bridge = Bridge()
    handlers = {"start": bridge.start, "ask": bridge.ask, "tell": bridge.tell, "save": bridge.save,
                "restore": bridge.restore}
    for line in sys.stdin:
        try:
            msg = json.loads(line)
            handler = handlers.get(msg.get("op"))
            if handler is None:
                raise ValueError("unknown op %r" % msg.get("op"))
            reply(handler(msg))
        except Exception as e:  # every failure is a reply calib names
            reply({"error": "%s: %s" % (type(e).__name__, e)})


if __name__ == "__main__":
    main()
