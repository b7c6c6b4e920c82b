#!/usr/bin/env python3
"""A participant written from docs/protocol.md alone joins a CURVE-encrypted run.

  test_doc_participant.py BUILD_DIR OUT

1. The reference: configs/verification/python_spring.yaml with its shipped participants.
2. The same scene over tcp with CURVE, its "left" participant external: doc_participant.py, which uses
   nothing but pyzmq, struct and the document, started with COSIM_CURVE_SERVER_KEY,
   COSIM_CURVE_SECRET_KEY_FILE and COSIM_TOKEN.
   Before it, two strangers with left's name and token (one PLAIN, one CURVE with an unlisted key) are
   dropped in the handshake: only the listed key gets in. Both the participant and the PLAIN stranger
   reach the coupler through a relay that records every byte: the participant's session holds none of its
   name, token, field names or values (the traffic is encrypted), where the same participant's session in
   a PLAIN run over loopback tcp, recorded the same way, shows them (the recording can see clear text).
3. Both runs end ok; the right half's results (tip displacement, interface reaction) equal the reference's
   to 1e-12 relative, and the interface displacement equals the analytic u = F/k of the scene files.
Exit 0 if all holds, 1 with the reasons otherwise.
"""
import os
import select
import shutil
import socket
import struct
import subprocess
import sys
import threading

import h5py
import yaml
import zmq

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
SCENE = os.path.join(SOURCE, "configs", "verification", "python_spring.yaml")
PARTICIPANT = os.path.join(HERE, "doc_participant.py")
TOKEN = "doc-participant-token-0123456789"
RTOL = 1e-12

failures = []


def check(ok, what):
    print(("ok      " if ok else "FAILED  ") + what, flush=True)
    if not ok:
        failures.append(what)


def close(a, b, rtol=RTOL):
    return abs(a - b) <= rtol * max(abs(a), abs(b))


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def load(path):
    with open(path) as f:
        return yaml.safe_load(f)


def right_results(folder):
    """The right half's view of the interface: its tip displacement and its interface reaction."""
    summary = load(os.path.join(folder, "right", "summary.yaml"))["results"]
    with h5py.File(os.path.join(folder, "right", "fem.h5"), "r") as f:
        tip_ux = float(f["timeseries/probes/tip_ux"][-1])
        reaction = float(f["timeseries/reactions/line_fx"][-1])
    return {"summary tip_displacement x": float(summary["tip_displacement"][0]),
            "fem.h5 tip_ux": tip_ux, "fem.h5 reaction line_fx": reaction}


def analytic():
    """u = F/k from the scene files: k from the left participant's --k, F the right half's end load."""
    scene = load(SCENE)
    cmd = [str(x) for x in scene["participants"]["left"]["command"]]
    k = float(cmd[cmd.index("--k") + 1])
    right_scene = os.path.join(os.path.dirname(SCENE), scene["participants"]["right"]["command"][1])
    loads = load(right_scene)["loads"]
    force = sum(float(l["force"][0]) for l in loads if l.get("type") == "force")
    return k, force, force / k


class Relay(threading.Thread):
    """A TCP relay from a local port to `target` (host, port) that records every byte in both directions:
    what anyone on the wire would see."""

    def __init__(self, target):
        super().__init__(daemon=True)
        self.target, self.recorded = target, bytearray()
        self.server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.server.bind(("127.0.0.1", 0))
        self.server.listen(8)
        self.endpoint = f"tcp://127.0.0.1:{self.server.getsockname()[1]}"
        self.start()

    def run(self):
        pairs = {}
        while True:
            try:
                ready, _, _ = select.select([self.server, *pairs], [], [], 0.2)
            except (OSError, ValueError):
                return
            for sock in ready:
                if sock is self.server:
                    client, _ = self.server.accept()
                    upstream = None
                    for _ in range(100):  # the coupler may not listen yet
                        try:
                            upstream = socket.create_connection(self.target)
                            break
                        except OSError:
                            threading.Event().wait(0.05)
                    if upstream is None:
                        client.close()
                        continue
                    pairs[client], pairs[upstream] = upstream, client
                    continue
                try:
                    data = sock.recv(65536)
                except OSError:
                    data = b""
                if data:
                    self.recorded += data
                    try:
                        pairs[sock].sendall(data)
                        continue
                    except OSError:
                        pass
                other = pairs.pop(sock, None)
                pairs.pop(other, None)
                for s in (sock, other):
                    if s is not None:
                        s.close()


def stranger(endpoint, mechanism, server_public):
    """A peer with the right name and token but not the coupler's CURVE pair: the handshake must drop it
    (no answer at all). Returns what it received, None if nothing (the expected outcome)."""
    ctx = zmq.Context()
    s = ctx.socket(zmq.DEALER)
    s.linger = 0
    if mechanism == "plain":
        s.plain_username, s.plain_password = b"left", TOKEN.encode()
    else:  # a key pair the scene does not list
        public, secret = zmq.curve_keypair()
        s.curve_serverkey, s.curve_publickey, s.curve_secretkey = server_public.encode(), public, secret
    s.connect(endpoint)
    fields = [(b"name:left", b""), (f"token:{TOKEN}".encode(), b"")]
    head = struct.pack("<IHHQIIddddII", 0x4D534F43, 2, 1, 0, 0, 0, 0.0, 0.0, 0.0, 0.0, len(fields), 0)
    s.send_multipart([head] + [x for pair in fields for x in pair])
    got = s.recv_multipart() if s.poll(1500) else None
    s.close()
    ctx.term()
    return got


def main():
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    build, out = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    cosim = os.path.join(build, "bin", "cosim")
    os.makedirs(out, exist_ok=True)
    for old in ("reference", "curve", "doc_participant"):
        shutil.rmtree(os.path.join(out, old), ignore_errors=True)
    env = dict(os.environ)
    env["PATH"] = os.path.join(build, "bin") + os.pathsep + env.get("PATH", "")
    for var in ("COSIM_TOKEN", "COSIM_TOKEN_FILE", "COSIM_CURVE_SERVER_KEY", "COSIM_CURVE_SECRET_KEY",
                "COSIM_CURVE_SECRET_KEY_FILE", "COSIM_COUPLER_PID"):
        env.pop(var, None)

    k, force, u_exact = analytic()
    print(f"analytic: k = {k:g} N/m, F = {force:g} N, u = F/k = {u_exact:.17g} m", flush=True)

    # a) the reference run with the shipped participants
    reference = os.path.join(out, "reference")
    r = subprocess.run([cosim, "run", SCENE, "--out", reference, "--quiet"], env=env, timeout=120)
    check(r.returncode == 0, f"reference run exits 0 (got {r.returncode})")
    if r.returncode != 0:
        return report()
    ref = right_results(reference)
    ref_left = load(os.path.join(reference, "left", "summary.yaml"))["results"]

    # b) keys, then the CURVE run with doc_participant.py as the external "left"
    for prefix in ("server", "client"):
        for ext in (".secret", ".public"):
            if os.path.exists(os.path.join(out, prefix + ext)):
                os.remove(os.path.join(out, prefix + ext))
        r = subprocess.run([cosim, "keys", os.path.join(out, prefix)], env=env, stdout=subprocess.DEVNULL)
        check(r.returncode == 0, f"cosim keys {prefix} exits 0 (got {r.returncode})")
        if r.returncode != 0:
            return report()
    with open(os.path.join(out, "server.public")) as f:
        server_public = f.readline().strip()
    with open(os.path.join(out, "client.public")) as f:
        client_public = f.readline().strip()

    curve = os.path.join(out, "curve")
    joined = os.path.join(out, "doc_participant")
    for attempt in range(3):  # a port taken between free_port() and the bind: try another
        shutil.rmtree(curve, ignore_errors=True)
        port = free_port()
        endpoint = f"tcp://127.0.0.1:{port}"
        coupler = subprocess.Popen(
            [cosim, "run", SCENE, "--out", curve, "--quiet",
             "--set", "participants.left.command=null",
             "--set", "participants.left.external=true",
             "--set", f"participants.left.token={TOKEN}",
             "--set", f"coupling.endpoint={endpoint}",
             "--set", f"coupling.curve.secret_key_file={os.path.join(out, 'server.secret')}",
             "--set", f'coupling.curve.allowed_keys=["{client_public}"]'],
            env=env)
        # Through relays that record the wire: one for the PLAIN stranger (the recording must show its
        # clear text), one for the participant (it must show none).
        wire = Relay(("127.0.0.1", port))
        strangers = {m: stranger(endpoint, m, server_public) for m in ("plain", "curve")}
        penv = dict(env, COSIM_CURVE_SERVER_KEY=server_public,
                    COSIM_CURVE_SECRET_KEY_FILE=os.path.join(out, "client.secret"), COSIM_TOKEN=TOKEN)
        participant = subprocess.Popen(
            [sys.executable, PARTICIPANT, "--name", "left", "--couple", wire.endpoint, "--k", repr(k),
             "--x", "5", "0", "0", "--out", joined, "--timeout", "30"], env=penv)
        try:
            coupler_rc = coupler.wait(timeout=120)
        except subprocess.TimeoutExpired:
            coupler.kill()
            coupler_rc = coupler.wait()
        try:
            participant_rc = participant.wait(timeout=40)
        except subprocess.TimeoutExpired:
            participant.kill()
            participant_rc = participant.wait()
        log = ""
        if os.path.exists(os.path.join(curve, "cosim.log")):
            with open(os.path.join(curve, "cosim.log")) as f:
                log = f.read()
        if coupler_rc != 0 and "ddress already in use" in log and attempt < 2:
            print(f"port {port} was taken, retrying", flush=True)
            continue
        break

    # c) checks
    check(coupler_rc == 0, f"CURVE run: cosim exits 0 (got {coupler_rc})")
    check(participant_rc == 0, f"CURVE run: doc_participant.py exits 0 (got {participant_rc})")
    if coupler_rc != 0 or participant_rc != 0:
        print(log[-4000:], file=sys.stderr)
        return report()
    summary = load(os.path.join(curve, "summary.yaml"))
    check(summary.get("status") == "ok", f"CURVE run: summary status ok (got {summary.get('status')})")
    check(endpoint in log, f"CURVE run: the coupler listened on {endpoint}")
    for mechanism, got in strangers.items():
        check(got is None, f"CURVE run: a {mechanism.upper()} stranger with left's name and token gets no answer")
    refused = summary["results"].get("refused_connections")
    # The CURVE stranger fails the coupler's ZAP check: logged and counted. The PLAIN one is dropped by
    # ZeroMQ itself (a mechanism mismatch never reaches ZAP), so it need not be in the count.
    check(isinstance(refused, int) and refused >= 1,
          f"CURVE run: the CURVE stranger is counted in refused_connections (got {refused}, want >= 1)")
    check("in the handshake" in log and "not in coupling.curve.allowed_keys" in log,
          "CURVE run: the log names the unlisted key's refusal in the handshake")

    # The wire: none of the encrypted session is readable (not the token, the name, a field name or the
    # interface value); the same session under PLAIN, recorded the same way, shows all of them.
    ref_u = float(ref_left["displacement"])
    secrets = [TOKEN.encode(), b"name:left", b"displacement", b"force", struct.pack("<d", ref_u)]
    seen = [x for x in secrets if x in wire.recorded]
    check(len(wire.recorded) > 1000 and not seen,
          f"wire: {len(wire.recorded)} bytes of the CURVE session hold no token, name, field name or interface "
          f"value in clear (found {seen})")
    plain = os.path.join(out, "plain")
    shutil.rmtree(plain, ignore_errors=True)
    port = free_port()
    plain_wire = Relay(("127.0.0.1", port))
    coupler = subprocess.Popen(
        [cosim, "run", SCENE, "--out", plain, "--quiet", "--set", "participants.left.command=null",
         "--set", "participants.left.external=true", "--set", f"participants.left.token={TOKEN}",
         "--set", f"coupling.endpoint=tcp://127.0.0.1:{port}"], env=env)
    participant = subprocess.Popen(
        [sys.executable, PARTICIPANT, "--name", "left", "--couple", plain_wire.endpoint, "--k", repr(k),
         "--x", "5", "0", "0", "--out", os.path.join(out, "plain_participant"), "--timeout", "30", "--quiet"],
        env=dict(env, COSIM_TOKEN=TOKEN))
    plain_rc = coupler.wait(timeout=120)
    participant.wait(timeout=40)
    shown = [x for x in secrets if x in plain_wire.recorded]
    check(plain_rc == 0 and shown == secrets,
          f"wire: the same session under PLAIN (exit {plain_rc}) shows {len(shown)} of the {len(secrets)} in clear")

    got = right_results(curve)
    for key, value in ref.items():
        check(close(got[key], value), f"{key}: {got[key]!r} equals the reference's {value!r} to {RTOL:g}")

    mine = load(os.path.join(joined, "summary.yaml"))["results"]
    u, f = float(mine["displacement"][0]), float(mine["force"][0])
    check(close(u, float(ref_left["displacement"])),
          f"interface displacement {u!r} equals the reference's {float(ref_left['displacement'])!r} to {RTOL:g}")
    check(close(f, float(ref_left["force"])),
          f"interface force {f!r} equals the reference's {float(ref_left['force'])!r} to {RTOL:g}")
    check(close(u, u_exact), f"interface displacement {u!r} equals the analytic F/k = {u_exact!r} to {RTOL:g}")
    check(close(-got["fem.h5 reaction line_fx"], force),
          f"interface reaction {-got['fem.h5 reaction line_fx']!r} equals the load {force:g} N to {RTOL:g}")
    check(mine["displacement"][1:] == [0.0, 0.0], "interface displacement has no y, z component")
    return report()


def report():
    if failures:
        print(f"\n{len(failures)} check(s) failed:", file=sys.stderr)
        for what in failures:
            print("  " + what, file=sys.stderr)
        return 1
    print("\nall checks passed: a participant written from docs/protocol.md joined the CURVE run")
    return 0


if __name__ == "__main__":
    sys.exit(main())
