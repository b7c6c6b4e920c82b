"""A cosim participant in pure Python (python3-zmq), written from docs/protocol.md alone.

Use:
    p = Participant("left", "ipc:///path/cosim.sock")
    p.add_mesh("interface", nodes=[x, y, z, ...], triangles=[])
    p.add_read("interface", "force", 3); p.add_write("interface", "displacement", 3)
    p.initialize()
    while (w := p.next_window()) is not None:
        if w.restore_checkpoint: ...; if w.save_checkpoint: ...
        f = p.read("interface", "force")          # list of floats
        p.write("interface", "displacement", u)
        p.complete(solver_seconds=seconds)         # the solver's own time in this pass
A participant that can repeat a window after its solver diverged calls initialize(retries=True) and, when
p.retries is then true, answers a diverged iteration with p.diverged(reason) instead of p.fail(reason).
"""
import math
import os
import struct
import time
from dataclasses import dataclass

import zmq

MAGIC, VERSION = 0x4D534F43, 2
HELLO, WELCOME, ADVANCE, RESULT, FINALIZE, ERROR, HEARTBEAT, BYE = range(1, 9)
SAVE, RESTORE, LAST, OUTPUT = 1, 2, 4, 8
DIVERGED = 64  # RESULT flag: the solver diverged in this iteration
RETRIES = 8    # feature bit: this participant answers a divergence with a RESULT flagged DIVERGED
# magic u32, version u16, type u16, window u64, iteration u32, flags u32, time f64, dt f64,
# value0 f64, value1 f64, field_count u32, features u32: 64 bytes, little-endian.
HEADER = struct.Struct("<IHHQIIddddII")
assert HEADER.size == 64


@dataclass
class Window:
    index: int
    iteration: int
    time: float
    dt: float
    save_checkpoint: bool
    restore_checkpoint: bool


def substeps(window_dt, dt):
    """The number of whole steps of at most dt in a window of window_dt, as libcosim's window loop counts
    them (a window a rounding error longer than a whole number of steps takes no extra step)."""
    return max(1, math.ceil(window_dt / dt * (1.0 - 1e-12)))


class CouplingError(RuntimeError):
    pass


class Participant:
    def __init__(self, name, endpoint, timeout_s=60.0, token=None):
        """timeout_s: the coupler's silence (it sends heartbeats about once a second while it waits) that
        means it is gone. token: this participant's credential; None: $COSIM_TOKEN, else the first line
        of the file $COSIM_TOKEN_FILE."""
        self.name, self.endpoint, self.timeout_s = name, endpoint, timeout_s
        if token is None:
            token = os.environ.get("COSIM_TOKEN", "")
            if not token and os.environ.get("COSIM_TOKEN_FILE"):
                with open(os.environ["COSIM_TOKEN_FILE"]) as f:
                    token = f.readline().strip()
        self.token = token
        self.context = zmq.Context.instance()
        self.socket = self.context.socket(zmq.DEALER)
        self.socket.setsockopt(zmq.LINGER, 1000)
        server = os.environ.get("COSIM_CURVE_SERVER_KEY")
        if server:  # CURVE: the coupler's public key and this participant's key pair (given or fresh)
            secret = os.environ.get("COSIM_CURVE_SECRET_KEY", "")
            if not secret and os.environ.get("COSIM_CURVE_SECRET_KEY_FILE"):
                with open(os.environ["COSIM_CURVE_SECRET_KEY_FILE"]) as f:
                    secret = f.readline().strip()
            public, secret = (zmq.curve_public(secret.encode()), secret.encode()) if secret else zmq.curve_keypair()
            self.socket.setsockopt(zmq.CURVE_SERVERKEY, server.encode())
            self.socket.setsockopt(zmq.CURVE_PUBLICKEY, public)
            self.socket.setsockopt(zmq.CURVE_SECRETKEY, secret)
        else:  # PLAIN: the name and token prove this participant in the handshake (docs/protocol.md)
            self.socket.setsockopt(zmq.PLAIN_USERNAME, name.encode())
            self.socket.setsockopt(zmq.PLAIN_PASSWORD, token.encode())
        self.socket.connect(endpoint)
        self.hello_fields, self.reads, self.writes = [], [], []
        self.inputs, self.outputs, self.header = {}, {}, None

    @staticmethod
    def _pack(values):
        return struct.pack(f"<{len(values)}d", *values)

    def _send(self, kind, fields=(), text=None, header=None):
        h = header or {}
        frames = [HEADER.pack(MAGIC, VERSION, kind, h.get("window", 0), h.get("iteration", 0), h.get("flags", 0),
                              h.get("time", 0.0), h.get("dt", 0.0), h.get("value0", 0.0), h.get("value1", 0.0),
                              0 if kind == ERROR else len(fields), h.get("features", 0))]
        if kind == ERROR:
            frames.append(text.encode())
        for name, values in fields:
            frames += [name.encode(), self._pack(values)]
        self.socket.send_multipart(frames)

    def _coupler_gone(self):
        pid = int(os.environ.get("COSIM_COUPLER_PID", "0"))
        if pid <= 0 or os.getppid() == pid:
            return False
        try:
            os.kill(pid, 0)
            return False
        except ProcessLookupError:
            return True
        except PermissionError:
            return False

    def _receive(self, waiting_for):
        heard = time.monotonic()
        while True:  # the coupler's heartbeats only prove it is there
            if not self.socket.poll(250):
                if self._coupler_gone():
                    raise CouplingError(f"participant {self.name}: the coupler is gone while waiting for {waiting_for}")
                if time.monotonic() - heard > self.timeout_s:
                    raise CouplingError(f"participant {self.name}: no {waiting_for} and no heartbeat from the coupler "
                                        f"within {self.timeout_s} s: the coupler is gone or stopped")
                continue
            heard = time.monotonic()
            frames = self.socket.recv_multipart()
            magic, version, kind, window, iteration, flags, t, dt, v0, v1, count, features = HEADER.unpack(frames[0])
            if magic != MAGIC or version != VERSION:
                raise CouplingError(f"participant {self.name}: bad magic or protocol version {version}")
            if kind == ERROR:
                raise CouplingError(f"the coupler stopped the run: {frames[1].decode()}")
            if kind != HEARTBEAT:
                break
        fields = {}
        for i in range(count):
            data = frames[2 + 2 * i]
            fields[frames[1 + 2 * i].decode()] = list(struct.unpack(f"<{len(data) // 8}d", data))
        return dict(kind=kind, window=window, iteration=iteration, flags=flags, time=t, dt=dt, value0=v0,
                    value1=v1, features=features), fields

    def add_mesh(self, mesh, nodes, triangles=()):
        self.hello_fields += [(f"mesh:{mesh}/nodes", list(nodes)), (f"mesh:{mesh}/triangles", [float(t) for t in triangles])]

    def add_read(self, mesh, field, components):
        self.reads.append(f"{mesh}/{field}")
        self.hello_fields.append((f"read:{mesh}/{field}", [float(components)]))

    def add_write(self, mesh, field, components):
        self.writes.append(f"{mesh}/{field}")
        self.hello_fields.append((f"write:{mesh}/{field}", [float(components)]))

    def initialize(self, retries=False):
        # Who this is: the name and the run's token, as fields without values (protocol version 2).
        self._send(HELLO, [(f"name:{self.name}", []), (f"token:{self.token}", [])] + self.hello_fields,
                   header={"features": RETRIES if retries else 0})
        header, _ = self._receive("WELCOME")
        if header["kind"] != WELCOME:
            raise CouplingError(f"participant {self.name}: expected WELCOME")
        self.retries = bool(header["features"] & RETRIES)
        self.window_size, self.end_time = header["dt"], header["value0"]

    def next_window(self):
        header, fields = self._receive("ADVANCE or FINALIZE")
        if header["kind"] == FINALIZE:
            self._send(BYE)
            return None
        if header["kind"] != ADVANCE:
            raise CouplingError(f"participant {self.name}: unexpected message type {header['kind']}")
        missing = [r for r in self.reads if r not in fields]
        if missing:
            raise CouplingError(f"participant {self.name}: ADVANCE lacks {missing}")
        self.header, self.inputs, self.outputs = header, fields, {}
        return Window(header["window"], header["iteration"], header["time"], header["dt"],
                      bool(header["flags"] & SAVE), bool(header["flags"] & RESTORE))

    def read(self, mesh, field):
        return self.inputs[f"{mesh}/{field}"]

    def write(self, mesh, field, values):
        self.outputs[f"{mesh}/{field}"] = list(values)

    def complete(self, solver_seconds=0.0, stable_dt=0.0):
        """Send this iteration's writes. solver_seconds: the wall time the solver spent on it (from after
        its reads to before its writes); the coupler's summary books it as solver_time_NAME and counts
        the rest of the pass as coupling overhead, so leaving it at 0 charges the whole pass to the
        coupling. stable_dt: the solver's stable step, where it has one (0: none)."""
        header = dict(self.header, value0=solver_seconds, value1=stable_dt)
        self._send(RESULT, [(w, self.outputs[w]) for w in self.writes], header=header)

    def diverged(self, text):
        """The solver diverged in this iteration (only when self.retries): the coupler restores the window's
        start at the next ADVANCE, shorter, or ends the run."""
        self._send(RESULT, [(f"diverged:{text}", [])], header=dict(self.header, flags=DIVERGED))

    def fail(self, text):
        self._send(ERROR, text=text)
