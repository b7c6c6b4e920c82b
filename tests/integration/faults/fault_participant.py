#!/usr/bin/env python3
"""A participant that misbehaves on purpose: the mass-spring of coupler/python/mass_spring.py (m ü + k u = F
on one interface node, exact per window) with one fault injected at one phase of the protocol.

    fault_participant.py --fault FAULT --phase PHASE --marker FILE [--k K] [--m M] --couple … --name … --out …

Phases: start (before or instead of HELLO), first_window (on window 0's first ADVANCE), mid_iteration
(on window 2's second iteration), finalize (on FINALIZE, before or instead of BYE).
Faults: see FAULTS below. At the moment of the fault the participant writes the time (time.time()) to
`--marker`, so the harness can measure how long the run took to stop after it.
"""
import argparse
import math
import os
import pathlib
import signal
import struct
import sys
import threading
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3] / "coupler" / "python"))
import zmq  # noqa: E402

import cosim_participant as cp  # noqa: E402

FAULTS = {
    "none": "no fault (the reference run)",
    "kill9": "the process dies at once (SIGKILL)",
    "sigstop": "the process is stopped (SIGSTOP) and never continued",
    "ignore_sigterm": "goes silent and ignores SIGTERM",
    "heartbeat_only": "sends heartbeats forever but never answers",
    "garbage": "sends a frame that is not a cosim message",
    "truncated": "sends a 30-byte header",
    "wrong_version": "sends a message in protocol version 7",
    "nan": "sends a field holding NaN",
    "bad_utf8": "sends a field whose name is not UTF-8 (the coupler quotes it in its summary)",
    "linger": "answers (BYE at finalize) but then never exits and ignores SIGTERM",
    "coupler_killed": "kills its coupler (SIGKILL) and waits as if nothing happened",
    "stranger": "opens a second connection under its own name, with a wrong token, that forges results",
}
PHASES = ["start", "first_window", "mid_iteration", "finalize"]


def mark(path):
    pathlib.Path(path).write_text(repr(time.time()))


def hang_forever():
    while True:
        time.sleep(1)


def raw_header(kind, version=cp.VERSION, count=0):
    return cp.HEADER.pack(cp.MAGIC, version, kind, 0, 0, 0, 0.0, 0.0, 0.0, 0.0, count, 0)


def stranger(endpoint, name, stop):
    """A second connection claiming to be `name` with a wrong token, then forging RESULTs of a huge force."""
    ctx = zmq.Context.instance()
    s = ctx.socket(zmq.DEALER)
    s.setsockopt(zmq.LINGER, 0)
    s.connect(endpoint)
    forged = [(f"name:{name}", []), ("token:0123456789abcdef0123456789abcdef", []),
              ("mesh:interface/nodes", [5.0, 0.0, 0.0]), ("mesh:interface/triangles", []),
              ("read:interface/force", [3.0]), ("write:interface/displacement", [3.0])]
    frames = [raw_header(cp.HELLO, count=len(forged))]
    for n, v in forged:
        frames += [n.encode(), struct.pack(f"<{len(v)}d", *v)]
    s.send_multipart(frames)
    while not stop.is_set():
        frames = [raw_header(cp.RESULT, count=1), b"interface/displacement", struct.pack("<3d", 1.0, 0.0, 0.0)]
        s.send_multipart(frames)
        time.sleep(0.01)
    s.close()


class Faulty(cp.Participant):
    def __init__(self, args):
        super().__init__(args.name, args.couple, timeout_s=args.coupler_timeout)
        self.args = args
        self.stop_stranger = threading.Event()

    def inject(self):
        a, fault = self.args, self.args.fault
        if fault == "none":
            return
        mark(a.marker)
        if fault == "kill9":
            os.kill(os.getpid(), signal.SIGKILL)
        elif fault == "sigstop":
            os.kill(os.getpid(), signal.SIGSTOP)
            hang_forever()
        elif fault in ("ignore_sigterm", "linger"):
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
            hang_forever()
        elif fault == "heartbeat_only":
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
            while True:
                self._send(cp.HEARTBEAT)
                time.sleep(0.5)
        elif fault == "garbage":
            self.socket.send_multipart([b"this is not a cosim message"])
            hang_forever()
        elif fault == "truncated":
            self.socket.send_multipart([raw_header(cp.RESULT)[:30]])
            hang_forever()
        elif fault == "wrong_version":
            self.socket.send_multipart([raw_header(cp.RESULT, version=7)])
            hang_forever()
        elif fault == "nan":
            self.socket.send_multipart([raw_header(cp.RESULT, count=1), b"interface/displacement",
                                        struct.pack("<3d", float("nan"), 0.0, 0.0)])
            hang_forever()
        elif fault == "bad_utf8":
            self.socket.send_multipart([raw_header(cp.RESULT, count=1), b"interface/\xff\xfe\xc3(displacement",
                                        struct.pack("<3d", 0.0, 0.0, 0.0)])
            hang_forever()
        elif fault == "coupler_killed":
            os.kill(os.getppid(), signal.SIGKILL)
        elif fault == "stranger":
            threading.Thread(target=stranger, args=(self.args.couple, self.name, self.stop_stranger), daemon=True).start()
            time.sleep(0.2)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fault", choices=sorted(FAULTS), required=True)
    ap.add_argument("--phase", choices=PHASES, required=True)
    ap.add_argument("--marker", required=True)
    ap.add_argument("--k", type=float, default=4.0e6)
    ap.add_argument("--m", type=float, default=1.0)
    ap.add_argument("--coupler-timeout", type=float, default=10.0)
    ap.add_argument("--couple", required=True)
    ap.add_argument("--name", required=True)
    ap.add_argument("--out", default=".")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args()

    p = Faulty(args)
    p.add_mesh("interface", [5.0, 0.0, 0.0])
    p.add_read("interface", "force", 3)
    p.add_write("interface", "displacement", 3)
    if args.phase == "start":
        p.inject()
    u = v = 0.0
    try:
        p.initialize()
        saved = (u, v)
        while True:
            header, fields = p._receive("ADVANCE or FINALIZE")
            if header["kind"] == cp.FINALIZE:
                if args.phase == "finalize":
                    if args.fault == "linger":
                        p._send(cp.BYE)
                    p.inject()
                p._send(cp.BYE)
                break
            p.header, p.inputs, p.outputs = header, fields, {}
            if args.phase == "first_window" and header["window"] == 0 and header["iteration"] == 0:
                p.inject()
            if args.phase == "mid_iteration" and header["window"] == 2 and header["iteration"] == 1:
                p.inject()
            if header["flags"] & cp.RESTORE:
                u, v = saved
            if header["flags"] & cp.SAVE:
                saved = (u, v)
            f = p.read("interface", "force")[0]
            omega = math.sqrt(args.k / args.m)
            ue = f / args.k
            c, s = math.cos(omega * header["dt"]), math.sin(omega * header["dt"])
            u, v = ue + (u - ue) * c + v / omega * s, -(u - ue) * omega * s + v * c
            p.write("interface", "displacement", [u, 0.0, 0.0])
            p.complete()
    except cp.CouplingError as e:
        print(f"[fault_participant] error: {e}", file=sys.stderr)
        return 4
    finally:
        p.stop_stranger.set()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.yaml").write_text(f"scene: fault_participant\nstatus: ok\nexit_code: 0\nresults:\n"
                                      f"  displacement: {u!r}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
