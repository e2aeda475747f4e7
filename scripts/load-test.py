#!/usr/bin/env python3
"""A bounded load test of `calib serve` on the loopback address.

Starts a server (ephemeral port, a fresh state folder, --jobs 2), runs two
jobs alone and times them, then runs the same two jobs again while CLIENTS
clients read a job's status and results as fast as they can for SECONDS
seconds. Prints the requests per second, the latency percentiles, the
errors (any answer but 200, or no answer) and the jobs' slowdown against
running alone. Exit 0 when no request failed.

  cmake --build build --target calib
  scripts/load-test.py [--clients 50] [--seconds 60] [--budget 400]
"""

import argparse
import http.client
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import threading
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent

JOB = """
name: {name}
train: [push_centre]
model:
  substeps: 4
  mesh: {{edge_length_px: 40}}
parameters:
  - {{name: k_D,   lower: 10,   upper: 5000, scale: log}}
  - {{name: k_d,   lower: 0.01, upper: 50,   scale: log}}
  - {{name: k_A,   lower: 1,    upper: 5000, scale: log}}
  - {{name: k_phi, lower: 0.1,  upper: 1000, scale: log}}
  - {{name: mass,  fixed: 0.2}}
  - {{name: tau,   lower: 0,    upper: 0.5}}
optimizer: {{name: cmaes, settings: {{population: 8, initial_sigma: 0.3}}}}
budget: {{evaluations: {budget}}}
seed: {seed}
"""


class Api:
    def __init__(self, port, token):
        self.port, self.token = port, token

    def request(self, method, path, body=None):
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=30)
        headers = {"Authorization": "Bearer " + self.token}
        if body is not None:
            headers["Content-Type"] = "application/json"
            body = json.dumps(body)
        conn.request(method, path, body=body, headers=headers)
        response = conn.getresponse()
        data = response.read()
        conn.close()
        return response.status, data


def run_jobs(api, names, budget):
    """Submits the jobs (seeds 1, 2, ...) and waits for them; seconds each took."""
    start = {}
    for seed, name in enumerate(names, 1):
        status, data = api.request("POST", "/api/v1/jobs",
                                   {"spec": JOB.format(name=name, budget=budget, seed=seed)})
        if status != 201:
            sys.exit(f"submit {name}: HTTP {status}: {data.decode()}")
        start[name] = time.monotonic()
    took = {}
    while len(took) < len(names):
        for name in names:
            if name in took:
                continue
            status, data = api.request("GET", f"/api/v1/jobs/{name}")
            job = json.loads(data)
            if job["state"] not in ("queued", "running"):
                if job["status"] != "finished":
                    sys.exit(f"{name}: {job['status']}: {job['message']}")
                took[name] = time.monotonic() - start[name]
        time.sleep(0.2)
    return took


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--clients", type=int, default=50)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--budget", type=int, default=400, help="evaluations of each job")
    parser.add_argument("--calib", default=str(ROOT / "build" / "apps" / "calib"))
    args = parser.parse_args()

    state = pathlib.Path(tempfile.mkdtemp(prefix="calib_load_"))
    server = subprocess.Popen(
        [args.calib, "serve", "--data-root", str(ROOT / "examples"), "--state-dir", str(state),
         "--port", "0", "--port-file", str(state / "port"), "--jobs", "2",
         "--threads-per-job", "1", "--no-report"],
        stdout=subprocess.DEVNULL, stderr=open(state / "serve.log", "w"))
    try:
        while not (state / "port").exists():
            if server.poll() is not None:
                sys.exit(f"the server did not start: {(state / 'serve.log').read_text()}")
            time.sleep(0.05)
        api = Api(int((state / "port").read_text()), (state / "token").read_text().strip())

        alone = run_jobs(api, ["alone_1", "alone_2"], args.budget)

        latencies, errors, lock = [], [], threading.Lock()
        stop = time.monotonic() + args.seconds

        def client(index):
            paths = ["/api/v1/jobs/loaded_1", "/api/v1/jobs/loaded_1/results"]
            i = index
            while time.monotonic() < stop:
                path = paths[i % 2]
                i += 1
                t0 = time.monotonic()
                try:
                    status, _ = api.request("GET", path)
                    ok = status == 200
                    why = f"HTTP {status}"
                except Exception as e:  # no answer: an error too
                    ok, why = False, repr(e)
                with lock:
                    latencies.append(time.monotonic() - t0)
                    if not ok:
                        errors.append(f"{path}: {why}")

        loaded = {}
        jobs = threading.Thread(target=lambda: loaded.update(
            run_jobs(api, ["loaded_1", "loaded_2"], args.budget)))
        jobs.start()
        time.sleep(1.0)  # the first job is in the store
        stop = time.monotonic() + args.seconds
        clients = [threading.Thread(target=client, args=(i,)) for i in range(args.clients)]
        for c in clients:
            c.start()
        for c in clients:
            c.join()
        jobs.join()

        q = statistics.quantiles(latencies, n=100)
        print(f"{args.clients} clients for {args.seconds:.0f} s: {len(latencies)} requests, "
              f"{len(latencies) / args.seconds:.1f} requests/s, latency p50 {q[49] * 1e3:.1f} ms, "
              f"p99 {q[98] * 1e3:.1f} ms, max {max(latencies) * 1e3:.1f} ms, {len(errors)} errors")
        for e in errors[:10]:
            print("  error:", e)
        mean_alone = statistics.mean(alone.values())
        mean_loaded = statistics.mean(loaded.values())
        print(f"two jobs of {args.budget} evaluations: {mean_alone:.1f} s alone, "
              f"{mean_loaded:.1f} s under the load (slowdown x{mean_loaded / mean_alone:.2f}; "
              f"the load ran for the first {args.seconds:.0f} s of them)")
        return 0 if not errors else 1
    finally:
        server.terminate()
        server.wait(60)


if __name__ == "__main__":
    sys.exit(main())
