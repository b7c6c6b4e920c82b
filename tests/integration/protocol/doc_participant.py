#!/usr/bin/env python3
"""A cosim participant written from docs/protocol.md alone (pyzmq + struct, nothing from coupler/).

A linear spring of stiffness k on one node of mesh "interface": it reads the force field and answers the
displacement u = F / k (per component). Handshake: PLAIN (name + token) or, when
COSIM_CURVE_SERVER_KEY is set and not empty, CURVE with its own key pair from COSIM_CURVE_SECRET_KEY or
COSIM_CURVE_SECRET_KEY_FILE. Token: COSIM_TOKEN, else the first line of the file COSIM_TOKEN_FILE.

  doc_participant.py --name NAME --couple ENDPOINT --k K [--x X Y Z] [--mesh M] [--read F] [--write F]
                     [--components N] [--out DIR] [--timeout S] [--quiet]

Exit codes: 0 after FINALIZE/BYE; 4 on ERROR from the coupler, a malformed message or the coupler's
silence past --timeout (no WELCOME included); 2 on a usage or environment error.
"""
import argparse
import math
import os
import struct
import sys
import time

import zmq

MAGIC = 0x4D534F43
VERSION = 2
HELLO, WELCOME, ADVANCE, RESULT, FINALIZE, ERROR, HEARTBEAT, BYE = range(1, 9)
NAMES = {HELLO: "HELLO", WELCOME: "WELCOME", ADVANCE: "ADVANCE", RESULT: "RESULT", FINALIZE: "FINALIZE",
         ERROR: "ERROR", HEARTBEAT: "HEARTBEAT", BYE: "BYE"}
# magic u32, version u16, type u16, window u64, iteration u32, flags u32, time dt value0 value1 f64,
# field_count u32, features u32: 64 bytes, little-endian.
HEADER = struct.Struct("<IHHQIIddddII")
assert HEADER.size == 64
SAVE_CHECKPOINT, RESTORE_CHECKPOINT, WRITE_CHECKPOINT = 1 << 0, 1 << 1, 1 << 5


class ProtocolError(Exception):
    pass


def header(kind, field_count=0, window=0, iteration=0, flags=0, t=0.0, dt=0.0, value0=0.0, value1=0.0):
    return HEADER.pack(MAGIC, VERSION, kind, window, iteration, flags, t, dt, value0, value1, field_count, 0)


def f64(values):
    return struct.pack(f"<{len(values)}d", *values)


def message(kind, fields=(), **h):
    frames = [header(kind, len(fields), **h)]
    for name, values in fields:
        frames += [name.encode(), f64(values)]
    return frames


def parse(frames):
    if len(frames[0]) != HEADER.size:
        raise ProtocolError(f"header of {len(frames[0])} bytes, not {HEADER.size}")
    magic, version, kind, window, iteration, flags, t, dt, v0, v1, count, features = HEADER.unpack(frames[0])
    if magic != MAGIC:
        raise ProtocolError(f"bad magic 0x{magic:08x}")
    if version != VERSION:
        raise ProtocolError(f"protocol version {version}, this participant speaks {VERSION}")
    h = dict(kind=kind, window=window, iteration=iteration, flags=flags, time=t, dt=dt, value0=v0, value1=v1,
             features=features)
    if kind == ERROR:
        h["text"] = frames[1].decode("utf-8", "replace") if len(frames) > 1 else ""
        return h, {}
    if len(frames) != 1 + 2 * count:
        raise ProtocolError(f"{NAMES.get(kind, kind)}: field_count {count} but {len(frames) - 1} frames")
    fields = {}
    for i in range(count):
        name = frames[1 + 2 * i].decode()
        data = frames[2 + 2 * i]
        if len(data) % 8:
            raise ProtocolError(f"field {name}: {len(data)} bytes, not a whole number of float64")
        fields[name] = list(struct.unpack(f"<{len(data) // 8}d", data))
    return h, fields


def env(name):
    """An empty variable counts as unset (docs/protocol.md, joining step 4)."""
    value = os.environ.get(name, "")
    return value if value else None


def first_line(path):
    with open(path, "r", encoding="utf-8") as f:
        return f.readline().rstrip("\r\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--name", required=True)
    ap.add_argument("--couple", required=True, help="the coupler's endpoint")
    ap.add_argument("--k", type=float, required=True, help="spring stiffness [N/m]")
    ap.add_argument("--x", type=float, nargs=3, default=[5.0, 0.0, 0.0], help="the node [m]")
    ap.add_argument("--mesh", default="interface")
    ap.add_argument("--read", default="force")
    ap.add_argument("--write", default="displacement")
    ap.add_argument("--components", type=int, default=3)
    ap.add_argument("--out", help="folder for summary.yaml")
    ap.add_argument("--timeout", type=float, default=60.0, help="own limit for the coupler's silence [s]")
    ap.add_argument("--threads", type=int)  # accepted like a launched participant; unused
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args()

    def log(text):
        if not a.quiet:
            print(f"[{a.name}] {text}", flush=True)

    token = env("COSIM_TOKEN")
    if token is None and env("COSIM_TOKEN_FILE"):
        token = first_line(env("COSIM_TOKEN_FILE"))
    if token is None:
        print(f"[{a.name}] no token: set COSIM_TOKEN or COSIM_TOKEN_FILE", file=sys.stderr)
        return 2

    ctx = zmq.Context()
    s = ctx.socket(zmq.DEALER)
    s.linger = 5000
    server_key = env("COSIM_CURVE_SERVER_KEY")
    if server_key is not None:
        secret = env("COSIM_CURVE_SECRET_KEY")
        if secret is None and env("COSIM_CURVE_SECRET_KEY_FILE"):
            secret = first_line(env("COSIM_CURVE_SECRET_KEY_FILE"))
        if secret is None:
            print(f"[{a.name}] CURVE: COSIM_CURVE_SERVER_KEY is set but neither COSIM_CURVE_SECRET_KEY nor "
                  "COSIM_CURVE_SECRET_KEY_FILE", file=sys.stderr)
            return 2
        s.curve_serverkey = server_key.strip().encode()
        s.curve_secretkey = secret.strip().encode()
        s.curve_publickey = zmq.curve_public(secret.strip().encode())  # the doc gives only the secret key
        log("handshake: CURVE")
    else:
        s.plain_username = a.name.encode()
        s.plain_password = token.encode()
        log("handshake: PLAIN")
    s.connect(a.couple)

    coupler_pid = env("COSIM_COUPLER_PID")
    mesh, rname, wname, nc = a.mesh, f"{a.mesh}/{a.read}", f"{a.mesh}/{a.write}", a.components
    s.send_multipart(message(HELLO, [
        (f"name:{a.name}", []), (f"token:{token}", []),
        (f"mesh:{mesh}/nodes", list(a.x)), (f"mesh:{mesh}/triangles", []),
        (f"read:{rname}", [float(nc)]), (f"write:{wname}", [float(nc)])]))

    force, u = [0.0] * nc, [0.0] * nc
    welcomed, unused, windows = False, set(), 0
    poller = zmq.Poller()
    poller.register(s, zmq.POLLIN)
    code = 4
    try:
        while True:
            deadline = time.monotonic() + a.timeout
            frames = None
            while frames is None:
                if coupler_pid and not os.path.exists(f"/proc/{coupler_pid}"):
                    raise ProtocolError(f"the coupler (pid {coupler_pid}) is gone")
                left = deadline - time.monotonic()
                if left <= 0:
                    raise ProtocolError(f"nothing from the coupler for {a.timeout:g} s"
                                        + ("" if welcomed else " (no WELCOME: a refused handshake?)"))
                if poller.poll(min(left, 1.0) * 1000):
                    frames = s.recv_multipart()
            h, fields = parse(frames)
            kind = h["kind"]
            if kind == HEARTBEAT:
                continue
            if kind == ERROR:
                print(f"[{a.name}] ERROR from the coupler: {h['text']}", file=sys.stderr)
                code = 4
                break
            if kind == WELCOME:
                if welcomed:
                    raise ProtocolError("a second WELCOME")
                welcomed = True
                unused = {n[len("unused:"):] for n in fields if n.startswith("unused:")}
                log(f"WELCOME: window {h['dt']:g} s, end time {h['value0']:g} s"
                    + (f", unused {sorted(unused)}" if unused else ""))
                continue
            if not welcomed:
                raise ProtocolError(f"{NAMES.get(kind, kind)} before WELCOME")
            if kind == FINALIZE:
                s.send_multipart(message(BYE))
                log(f"FINALIZE after {windows} window(s): u = {u}, F = {force}")
                code = 0
                break
            if kind != ADVANCE:
                raise ProtocolError(f"unexpected message type {kind}")
            started = time.perf_counter()
            for name in fields:
                if name != rname and not name.startswith("checkpoint:"):
                    raise ProtocolError(f"ADVANCE: unknown field {name}")
            if rname not in fields:
                raise ProtocolError(f"ADVANCE without {rname}")
            values = fields[rname]
            if len(values) != nc:
                raise ProtocolError(f"ADVANCE: {rname} has {len(values)} values, not {nc}")
            if not all(math.isfinite(v) for v in values):
                raise ProtocolError(f"ADVANCE: {rname} is not finite")
            if h["iteration"] == 0:
                windows += 1
            # A static spring has no state: save/restore-checkpoint change nothing.
            force = values
            u = [f / a.k for f in force]
            out = [] if wname in unused else [(wname, u)]
            s.send_multipart(message(RESULT, out, window=h["window"], iteration=h["iteration"], t=h["time"],
                                     dt=h["dt"], value0=time.perf_counter() - started))
    except ProtocolError as e:
        print(f"[{a.name}] {e}", file=sys.stderr)
        try:
            s.send_multipart([header(ERROR), str(e).encode()])
        except zmq.ZMQError:
            pass
        code = 4
    finally:
        s.close()
        ctx.term()

    if a.out:
        os.makedirs(a.out, exist_ok=True)
        with open(os.path.join(a.out, "summary.yaml"), "w") as f:
            f.write(f"scene: doc_participant\nstatus: {'ok' if code == 0 else 'failed'}\nexit_code: {code}\n"
                    f"results:\n  windows: {windows}\n"
                    f"  displacement: [{', '.join(repr(v) for v in u)}]\n"
                    f"  force: [{', '.join(repr(v) for v in force)}]\n")
    return code


if __name__ == "__main__":
    sys.exit(main())
