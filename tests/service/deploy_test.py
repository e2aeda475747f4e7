"""docker/compose.yaml and docker/Dockerfile as far as they can be checked
without a container runtime: the compose file parses and runs `calib serve`
listening on 0.0.0.0 in its container, published on the host's loopback
address only, with --mpi-hosts naming the worker services, which run the
image's worker role and see the recordings and the state at the server's
paths; the Dockerfile installs with scripts/install-deps.sh and serves by
default; the entrypoint is valid bash. Exit 0 when all holds.

  python3 tests/service/deploy_test.py SOURCE_DIR
"""
import subprocess
import sys
from pathlib import Path

import yaml

source = Path(sys.argv[1])
failures = []


def check(condition, message):
    if not condition:
        failures.append(message)


compose = yaml.safe_load((source / "docker" / "compose.yaml").read_text())
services = compose["services"]
server = services["server"]
command = server["command"]
check(command[:2] == ["calib-entrypoint.sh", "server"], f"server command: {command}")
check(command[command.index("--listen") + 1] == "0.0.0.0", "the server does not listen on 0.0.0.0")
check(all(p.startswith("127.0.0.1:") for p in server["ports"]), f"ports beyond loopback: {server['ports']}")
hosts = command[command.index("--mpi-hosts") + 1].split(",")
names = [h.split(":")[0] for h in hosts]
check(names[0] == server["hostname"], f"rank 0 is not on the server: {hosts}")
workers = [n for n in services if n != "server"]
check(sorted(names[1:]) == sorted(workers), f"--mpi-hosts {hosts} against the workers {workers}")
mounts = {}
for name, service in services.items():
    targets = [v.rsplit("}", 1)[-1].split(":")[1] for v in service["volumes"]]
    check("/data" in targets and "/state" in targets and "/ssh" in targets, f"{name}: volumes {targets}")
    mounts[name] = service["volumes"]
    if name != "server":
        check(service["command"] == ["calib-entrypoint.sh", "worker"], f"{name}: command {service['command']}")
        check(service["hostname"] == name, f"{name}: hostname {service.get('hostname')}")
check(len({tuple(v) for v in mounts.values()}) == 1, "the services mount different volumes")
for volume in ("state", "ssh"):
    check(volume in compose["volumes"], f"volume {volume} not declared")

dockerfile = (source / "docker" / "Dockerfile").read_text()
check("RUN bash scripts/install-deps.sh" in dockerfile, "the Dockerfile does not call scripts/install-deps.sh")
cmd = next(line for line in dockerfile.splitlines() if line.startswith("CMD"))
check('"server"' in cmd and "calib-entrypoint.sh" in cmd, f"the image's default command: {cmd}")
check('"0.0.0.0"' in dockerfile and '"/state"' in dockerfile, "the image does not serve on 0.0.0.0 with /state")
entrypoint = source / "docker" / "calib-entrypoint.sh"
check(subprocess.run(["bash", "-n", str(entrypoint)]).returncode == 0, "calib-entrypoint.sh: bash syntax")
check("exec calib serve" in entrypoint.read_text(), "the server role does not run calib serve")

for f in failures:
    print("FAILED:", f)
if not failures:
    print(f"compose: server and {len(workers)} workers ({','.join(hosts)}); Dockerfile and entrypoint")
sys.exit(1 if failures else 0)
