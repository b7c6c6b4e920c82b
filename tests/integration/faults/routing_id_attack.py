#!/usr/bin/env python3
"""The routing-id attack, replayed over ipc, tcp and CURVE: a stranger must not stop the run.

Usage:  routing_id_attack.py BUILD_DIR OUT

libzmq 4.3 gives a ROUTER peer that sends no routing id of its own the next value of a counter that starts
at the same number in every process (0x006b8b4567: its random source is never seeded), and aborts the
process (an assertion) when that value is already held by a peer that chose it. A stranger that first
connects under the next sixteen values and then without an id used to kill the coupler with signal 6, no
summary written. The coupler now admits a connection only after the ZeroMQ handshake proved it (PLAIN:
a participant's name and token; CURVE: a listed key), so a stranger's connection never reaches the table
of routing ids.

Each transport: the dynamic python_spring scene once alone and once under attack (sixteen connections
with chosen ids in the counter's range, eight without, some with forged credentials: PLAIN with a
participant's name and a wrong token, CURVE with a key of their own), started once the coupler listens.
Checked: exit 0, the results equal to the unattacked run's to the last bit, and the handshake refusals
counted. Exits 1 on any failure.
"""
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import yaml
import zmq

ROOT = Path(__file__).resolve().parents[3]
SCENE = ROOT / "configs/verification/python_spring.yaml"
FIRST_ID = 0x6B8B4567


def attack(endpoint, stop, server_key=None):
    """Sockets with ids in the counter's range, then sockets without one, reconnecting until `stop`."""
    ctx = zmq.Context()
    sockets = []
    try:
        while not stop.is_set():
            for k in range(24):
                s = ctx.socket(zmq.DEALER)
                s.setsockopt(zmq.LINGER, 0)
                if k < 16:
                    s.setsockopt(zmq.ROUTING_ID, b"\x00" + (FIRST_ID + k).to_bytes(4, "big"))
                if server_key:  # a key pair of its own: not one the coupler lists
                    public, secret = zmq.curve_keypair()
                    s.setsockopt(zmq.CURVE_SERVERKEY, server_key.encode())
                    s.setsockopt(zmq.CURVE_PUBLICKEY, public)
                    s.setsockopt(zmq.CURVE_SECRETKEY, secret)
                elif k % 2:  # a participant's name with a made-up token
                    s.setsockopt(zmq.PLAIN_USERNAME, b"left")
                    s.setsockopt(zmq.PLAIN_PASSWORD, b"0123456789abcdef0123456789abcdef")
                s.connect(endpoint)
                s.send_multipart([b"COSM", b"garbage"], zmq.NOBLOCK)
                sockets.append(s)
            time.sleep(0.3)
            for s in sockets:
                s.close()
            sockets.clear()
    finally:
        for s in sockets:
            s.close()
        ctx.term()


def free_port():
    """A port the system has free now (a fixed one may be any connection's ephemeral port)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def lost_bind(out):
    """Whether the coupler's run ended on a port taken between free_port() and its bind."""
    console = out.parent / f"{out.name}.console.txt"
    return console.exists() and "Address already in use" in console.read_text()


def run(bin_dir, out, sets, endpoint=None, server_key=None, env=None):
    command = [str(bin_dir / "cosim"), "run", str(SCENE), "--out", str(out), "--quiet"]
    for s in sets:
        command += ["--set", s]
    out.mkdir(parents=True, exist_ok=True)
    proc = subprocess.Popen(command, stdout=open(out.parent / f"{out.name}.console.txt", "w"), stderr=subprocess.STDOUT,
                            env=env)
    stop = threading.Event()
    attacker = None
    if endpoint:
        time.sleep(0.3)  # the coupler binds at once; its participants are still starting
        attacker = threading.Thread(target=attack, args=(endpoint, stop, server_key))
        attacker.start()
    code = proc.wait(timeout=300)
    stop.set()
    if attacker:
        attacker.join()
    summary = yaml.safe_load((out / "summary.yaml").read_text()) if (out / "summary.yaml").exists() else {}
    return code, summary


def main(argv=None):
    argv = argv if argv is not None else sys.argv[1:]
    build, out = Path(argv[0]).resolve(), Path(argv[1]).resolve()
    bin_dir = build / "bin"
    out.mkdir(parents=True, exist_ok=True)
    failures = []
    # The scene's 10 windows take well under a second: stretched, so the attack meets the run under way.
    longer = ["coupling.time_window=1e-3", "coupling.end_time=0.4", "coupling.idle_cpus=sleep",
              "participants.left.command=[/usr/bin/python3, ../../coupler/python/mass_spring.py, --k, '4.0e6', --m, '1.0e3', "
              "--x, '5', '0', '0']"]
    sock_dir = Path(tempfile.mkdtemp(prefix="cosim-attack-"))
    keys = out / "curve_keys"
    subprocess.run([str(bin_dir / "cosim"), "keys", str(keys)], check=True, stdout=subprocess.DEVNULL)
    server_key = (Path(str(keys) + ".public")).read_text().strip()

    def case(name):  # (scene settings, endpoint, server key), a free port for each tcp run
        if name == "ipc":
            return [f"coupling.endpoint=ipc://{sock_dir}/run.sock"], f"ipc://{sock_dir}/run.sock", None
        endpoint = f"tcp://127.0.0.1:{free_port()}"
        curve = [f"coupling.curve.secret_key_file={keys}.secret"] if name == "curve" else []
        return [f"coupling.endpoint={endpoint}"] + curve, endpoint, server_key if name == "curve" else None

    def run_case(name, attacked):
        for attempt in range(3):  # another process took the port between free_port() and the bind
            sets, endpoint, key = case(name)
            to = out / f"{name}_{'attacked' if attacked else 'alone'}"
            code, summary = run(bin_dir, to, longer + sets, endpoint if attacked else None, key)
            if code != 2 or not lost_bind(to):
                break
        return code, summary

    for name in ("ipc", "tcp", "curve"):
        code0, alone = run_case(name, False)
        code, attacked = run_case(name, True)
        results0, results = alone.get("results") or {}, attacked.get("results") or {}
        differ = sorted(k for k in results0 if not k.endswith("_s") and not k.startswith(("solver_time", "zmq_round",
                        "outside_solvers", "coupling_overhead", "refused")) and results.get(k) != results0[k])
        refused = results.get("refused_connections", 0)
        print(f"{name}: alone exit {code0}, attacked exit {code} ({attacked.get('status', 'no summary')}), "
              f"refused {refused}, results that differ: {differ or 'none'}")
        if code0 != 0 or code != 0 or differ or refused == 0:
            failures.append(name)
    if failures:
        print("FAILED:", ", ".join(failures))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
