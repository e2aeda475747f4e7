#!/usr/bin/python3
"""A tiny external optimiser for tests/search/external_optimizer_test.cpp:
random points from its own seeded generator, its state that generator's
state, and ways to misbehave.

  fake_external_optimizer.py MODE [N]
    good             follows the protocol
    exit N           exits with status 3 at the N-th ask (1: the first)
    hang N           stops replying at the N-th ask
    garbage N        prints a line that is not JSON at the N-th ask
    outside N        proposes a point outside the box at the N-th ask
"""

import json
import sys

mode = sys.argv[1]
at = int(sys.argv[2]) if len(sys.argv) > 2 else 0
state = {"rng": 0, "pending": 0, "asks": 0}
box = {}


def uniform():
    state["rng"] = (state["rng"] * 6364136223846793005 + 1442695040888963407) % (2 ** 64)
    return (state["rng"] >> 11) / float(2 ** 53)


for line in sys.stdin:
    msg = json.loads(line)
    op = msg["op"]
    if op == "start":
        box = {"lower": msg["lower"], "upper": msg["upper"]}
        state["rng"] = msg["seed"] + 12345
        out = {"ok": True}
    elif op == "ask":
        state["asks"] += 1
        if state["asks"] == at:
            if mode == "exit":
                sys.exit(3)
            if mode == "hang":
                while True:
                    sys.stdin.readline()
            if mode == "garbage":
                print("hello, this is not JSON", flush=True)
                continue
        points = []
        for _ in range(msg["count"]):
            points.append([lo + uniform() * (hi - lo) for lo, hi in zip(box["lower"], box["upper"])])
        if mode == "outside" and state["asks"] == at:
            points[0][-1] = box["upper"][-1] + 0.5
        state["pending"] = len(points)
        out = {"points": points}
    elif op == "tell":
        if len(msg["results"]) != state["pending"]:
            out = {"error": "told %d of %d" % (len(msg["results"]), state["pending"])}
        else:
            state["pending"] = 0
            out = {"ok": True}
    elif op == "save":
        out = {"state": dict(state, box=box)}
    elif op == "restore":
        box = msg["state"].pop("box")
        state = msg["state"]
        out = {"ok": True}
    else:
        out = {"error": "unknown op"}
    print(json.dumps(out), flush=True)
