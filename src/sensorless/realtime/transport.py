"""Where ``sensorless stream`` reads samples and writes estimates, and its loop.

Endpoints: ``stdin``/``stdout``, ``udp://HOST:PORT`` (one record per datagram; on input an empty
datagram ends the stream; HOST must be a loopback address unless remote hosts are allowed) and
``ros2:TOPIC`` (:mod:`.ros2`). The loop holds one input and one output record (preallocated), a
fixed latency histogram and counters: its memory does not grow with the number of samples. It
stops cleanly at end of input, SIGINT or SIGTERM (the current sample is finished and written).

Latency is per sample, from the moment its record is read to the moment its estimate is written
(the stream's own processing; a sender measures send-to-receive, ``sensorless benchmark stream``).
"""

from __future__ import annotations

import ipaddress
import math
import os
import signal
import socket
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import DataError, OptionError, TimestampError, setting

__all__ = ["Endpoint", "Heartbeat", "LatencyHistogram", "RESTART_GAP", "RESTART_RUN", "StreamStats", "TooLong",
           "parse_endpoint", "run_stream"]


@dataclass(frozen=True)
class Endpoint:
    kind: str  # "stdio" | "udp" | "ros2"
    host: str = ""
    port: int = 0
    topic: str = ""

    def __str__(self) -> str:
        return {"stdio": "stdio", "udp": f"udp://{self.host}:{self.port}", "ros2": f"ros2:{self.topic}"}[self.kind]


def parse_endpoint(spec: str, option: str, allow_remote: bool = False) -> Endpoint:
    """``stdin``/``stdout``/``-``, ``udp://HOST:PORT`` or ``ros2:TOPIC``; OptionError naming ``option``."""
    s = spec.strip()
    if s in ("-", "stdin", "stdout"):
        return Endpoint("stdio")
    if s.startswith("ros2:"):
        topic = s[5:].strip()
        if not topic:
            raise OptionError(f"{option} {spec}: give the topic, e.g. ros2:/joint_states")
        return Endpoint("ros2", topic=topic if topic.startswith("/") or topic.startswith("~") else "/" + topic)
    if s.startswith("udp://"):
        host, _, port = s[6:].rpartition(":")
        host = host.strip("[]")
        try:
            p = int(port)
        except ValueError:
            p = -1
        if not host or not 0 <= p <= 65535:
            raise OptionError(f"{option} {spec}: expected udp://HOST:PORT, e.g. udp://127.0.0.1:9870")
        if not allow_remote and not _loopback(host):
            raise OptionError(f"{option} {spec}: {host} is not a loopback address; samples and estimates stay on this "
                              f"machine unless {setting('allow_remote', True)} is given")
        return Endpoint("udp", host, p)
    raise OptionError(f"{option} {spec}: expected stdin/stdout, udp://127.0.0.1:PORT or ros2:TOPIC")


def _loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        try:
            infos = socket.getaddrinfo(host, None)
        except OSError:
            return False
        return bool(infos) and all(ipaddress.ip_address(i[4][0]).is_loopback for i in infos)


class LatencyHistogram:
    """Latencies in fixed log-spaced bins (200 per decade, 100 ns to 100 s): bounded memory,
    quantiles to within 1.2 % (the upper edge of the bin), exact maximum."""

    PER_DECADE, LO = 200, -7.0

    def __init__(self) -> None:
        self.counts = np.zeros(int(9 * self.PER_DECADE) + 2, np.int64)
        self.n, self.max = 0, 0.0

    def add(self, seconds: float) -> None:
        i = int((math.log10(seconds) - self.LO) * self.PER_DECADE) + 1 if seconds > 0 else 0
        self.counts[min(max(i, 0), len(self.counts) - 1)] += 1
        self.n += 1
        self.max = max(self.max, seconds)

    def quantile(self, p: float) -> float | None:
        if not self.n:
            return None
        i = int(np.searchsorted(np.cumsum(self.counts), math.ceil(p * self.n)))
        return min(10 ** (self.LO + i / self.PER_DECADE), self.max)

    def summary(self) -> dict:
        us = lambda x: None if x is None else x * 1e6  # noqa: E731
        return {"p50_us": us(self.quantile(0.5)), "p99_us": us(self.quantile(0.99)),
                "p999_us": us(self.quantile(0.999)), "max_us": us(self.max if self.n else None)}


@dataclass
class StreamStats:
    samples: int = 0  # processed
    dropped: int = 0  # sequence gaps
    out_of_order: int = 0  # seq not above the last one: skipped
    bad: int = 0  # skipped with --skip-bad
    contact_samples: int = 0
    out_of_range: int = 0  # non-finite or out-of-range samples: flagged, never fed to the observer
    restarts: int = 0  # the sender restarted seq: the observer was re-initialised
    stopped_by: str = "end of input"
    latency: LatencyHistogram = field(default_factory=LatencyHistogram)

    def to_dict(self) -> dict:
        return {"samples": self.samples, "dropped": self.dropped, "out_of_order": self.out_of_order,
                "bad_skipped": self.bad, "contact_samples": self.contact_samples, "out_of_range": self.out_of_range,
                "restarts": self.restarts, "stopped_by": self.stopped_by, "latency": self.latency.summary()}

    def problems(self) -> int:
        """Records not answered as clean samples: gaps, out of order, bad, out of range."""
        return self.dropped + self.out_of_order + self.bad + self.out_of_range

    def line(self) -> str:
        lat = self.latency.summary()
        f = lambda x: "n/a" if x is None else f"{x:.0f} µs"  # noqa: E731
        return (f"stream: {self.samples} samples, {self.dropped} dropped (sequence gaps), {self.out_of_order} out of "
                f"order, {self.bad} bad skipped, {self.out_of_range} out of range (flagged), {self.restarts} "
                f"sequence restart(s), {self.contact_samples} in contact; latency p50 {f(lat['p50_us'])}, "
                f"p99 {f(lat['p99_us'])}, max {f(lat['max_us'])}; stopped by {self.stopped_by}")


#: a record this far behind the last seq is a restart of the sender, not a reordered one
RESTART_GAP = 64
#: this many consecutive records behind the last seq (each following the previous) are a restart too
RESTART_RUN = 3


class Heartbeat:
    """A line on stderr whenever records were dropped, skipped or refused since the last line (at most
    one per ``period`` seconds, the first at once); warnings (a sequence restart) go out at once."""

    def __init__(self, period: float = 1.0, write=None, clock=time.monotonic) -> None:
        self.period, self.clock = period, clock
        self.write = write or (lambda text: (sys.stderr.write(text), sys.stderr.flush()))
        self.last_time, self.last_count = -math.inf, 0

    def warn(self, text: str) -> None:
        self.write(f"stream: warning: {text}\n")

    def beat(self, stats: StreamStats, seq: float, why: str | None = None) -> None:
        n = stats.problems()
        if n == self.last_count:
            return
        now = self.clock()
        if now - self.last_time < self.period:
            return
        self.last_time, self.last_count = now, n
        self.write(f"stream: at seq {int(seq)}: {stats.dropped} dropped, {stats.out_of_order} out of order, "
                   f"{stats.bad} bad, {stats.out_of_range} out of range so far" + (f" (last: {why})" if why else "")
                   + "\n")


class _Stop(Exception):
    pass


class _Signals:
    """SIGINT/SIGTERM: stop after the current sample; while blocked reading, stop at once."""

    def __init__(self) -> None:
        self.name: str | None = None
        self.reading = False
        self._old: dict = {}

    def __enter__(self) -> "_Signals":
        import threading

        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handle)
        return self

    def _handle(self, signum, frame) -> None:
        self.name = signal.Signals(signum).name
        if self.reading:
            raise _Stop

    def __exit__(self, *exc) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)


class TooLong(bytes):
    """A CSV line longer than the bound (its first bytes; the rest was read and dropped)."""


def _bounded_line(stream, limit: int) -> bytes:
    """One line of at most ``limit`` bytes; a longer one is read to its end in ``limit`` pieces and
    returned as :class:`TooLong` (memory stays bounded whatever the sender writes)."""
    line = stream.readline(limit)
    if len(line) < limit or line.endswith(b"\n"):
        return line
    while True:
        rest = stream.readline(limit)
        if not rest or rest.endswith(b"\n"):
            return TooLong(line[:64])


def _records(src: Endpoint, fmt: str, size: int, sig: _Signals, limit: int):
    """Yield raw records (bytes) from the input until its end; CSV lines of at most ``limit`` bytes."""
    if src.kind == "stdio":
        stream = sys.stdin.buffer
        while True:
            sig.reading = True
            try:
                data = _bounded_line(stream, limit) if fmt == "csv" else stream.read(size)
            finally:
                sig.reading = False
            if not data:
                return
            yield data
        return
    sock = socket.socket(socket.AF_INET6 if ":" in src.host else socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)  # absorb stalls (capped by the kernel)
        try:
            sock.bind((src.host, src.port))
        except OSError as e:
            raise OptionError(f"{setting('input', f'udp://{src.host}:{src.port}')}: cannot listen there ({e.strerror})") from None
        rcv = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        sys.stderr.write(f"stream: listening on udp://{src.host}:{sock.getsockname()[1]} (kernel receive buffer "
                         f"{rcv / 2**20:.1f} MiB)\n")
        sys.stderr.flush()
        buf = bytearray(65536)
        while True:
            sig.reading = True
            try:
                n = sock.recv_into(buf)
            finally:
                sig.reading = False
            if n == 0:
                return
            data = bytes(buf[:n])
            if fmt == "csv":
                yield from (line if len(line) <= limit else TooLong(line[:64])
                            for line in data.splitlines() if line.strip())
            elif n % size == 0:  # several records in one datagram are read in order
                yield from (data[i : i + size] for i in range(0, n, size))
            else:
                yield data  # the parser names the wrong size
    finally:
        sock.close()


class _Sink:
    def __init__(self, dst: Endpoint, layout, fmt: str) -> None:
        self.fmt, self.layout, self.sock = fmt, layout, None
        if dst.kind == "udp":
            self.sock = socket.socket(socket.AF_INET6 if ":" in dst.host else socket.AF_INET, socket.SOCK_DGRAM)
            self.sock.connect((dst.host, dst.port))
        elif fmt == "csv":
            self._write(layout.csv_header())

    def _write(self, data: bytes) -> None:
        if self.sock is not None:
            try:
                self.sock.send(data)
            except ConnectionRefusedError:  # nobody listening yet: UDP drops it, as the network would
                pass
            return
        view = memoryview(data)
        while view:
            view = view[os.write(1, view):]

    def write(self, rec: np.ndarray) -> None:
        self._write(self.layout.format_csv(rec) if self.fmt == "csv" else self.layout.format_binary(rec))

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()


def run_stream(monitor, src: Endpoint, dst: Endpoint, fmt: str, *, out_fmt: str | None = None,
               skip_bad: bool = False, max_samples: int | None = None, heartbeat: Heartbeat | None = None) -> StreamStats:
    """Read records from ``src``, write one estimate per sample to ``dst`` (module docstring).
    ``monitor``: a :class:`~.monitor.StreamMonitor`. Bad records raise DataError naming the record
    and field, or are counted and skipped with ``skip_bad``. Samples the monitor refuses (non-finite,
    out of range) are answered flagged and counted. A ``seq`` far behind the last one (or a run of
    records behind it) is the sender restarting: the monitor is re-initialised and a warning written
    at once. ``heartbeat`` (default: stderr) reports dropped, skipped and refused records as they happen."""
    from .records import max_line

    layout, th = monitor.layout, monitor.th
    out_fmt = out_fmt or fmt
    beat = heartbeat or Heartbeat()
    nj, na = len(layout.joints), len(layout.actuated)
    rec = np.zeros(layout.n_in)
    stats = StreamStats()
    last_seq = last_t = None
    behind: list = []  # consecutive records behind last_seq (a restart in the making)
    clock = time.perf_counter
    sink = _Sink(dst, layout, out_fmt)
    index = 0
    contacts = 0  # of the monitor runs before a restart
    try:
        with _Signals() as sig:
            try:
                for data in _records(src, fmt, layout.in_bytes, sig, max_line(layout.n_in)):
                    t_in = clock()
                    index += 1
                    why = None
                    try:
                        if isinstance(data, TooLong):
                            raise DataError(f"record {index}: a line longer than {max_line(layout.n_in)} bytes "
                                            f"(starting {data[:40].decode(errors='replace')!r}); not a record")
                        if fmt == "csv":
                            if not layout.parse_csv(data, index, rec):
                                index -= 1
                                continue
                        else:
                            layout.parse_binary(data, index, rec)
                        seq, t = rec[0], rec[1]
                        if seq != int(seq) or seq < 0:
                            raise DataError(f"record {index}, field seq: {seq!r} is not a sample counter (an integer ≥ 0)")
                        if last_seq is not None and seq <= last_seq:
                            behind = behind + [seq] if behind and seq == behind[-1] + 1 else [seq]
                            if last_seq - seq > RESTART_GAP or len(behind) >= RESTART_RUN:
                                stats.restarts += 1
                                beat.warn(f"record {index}: seq went back from {int(last_seq)} to {int(seq)}: the "
                                          f"sender restarted; observer re-initialised (warm-up {th.warmup_s:g} s)")
                                contacts += monitor.contact_samples
                                monitor.reset(counts=False)
                                monitor.contact_samples = 0
                                last_seq = last_t = None
                                behind = []
                            else:
                                stats.out_of_order += 1
                                beat.beat(stats, seq, "out of order")
                                continue
                        behind = []
                        if last_seq is not None:
                            gap = seq - last_seq
                            if abs((t - last_t) - gap * th.dt) > 0.25 * th.dt:
                                raise TimestampError(
                                    f"record {index} (seq {int(seq)}): t advances by {t - last_t:.6g} s over {int(gap)} "
                                    f"sample(s); the thresholds' sample period is {th.dt:.6g} s ({th.source})")
                    except DataError as e:
                        if not skip_bad:
                            raise
                        stats.bad += 1
                        beat.beat(stats, rec[0], str(e))
                        continue
                    if last_seq is not None:
                        stats.dropped += int(seq - last_seq) - 1
                        why = "sequence gap" if seq - last_seq > 1 else None
                    last_seq, last_t = seq, t
                    refused = monitor.rejected
                    out = monitor.step(seq, t, rec[2 : 2 + nj], rec[2 + nj : 2 + 2 * nj], rec[2 + 2 * nj : 2 + 2 * nj + na])
                    if monitor.rejected != refused:
                        stats.out_of_range += 1
                        why = monitor.last_rejected
                    sink.write(out)
                    stats.latency.add(clock() - t_in)
                    stats.samples += 1
                    if why:
                        beat.beat(stats, seq, why)
                    if sig.name:
                        raise _Stop
                    if max_samples and stats.samples >= max_samples:
                        stats.stopped_by = setting("max_samples", max_samples)
                        break
            except _Stop:
                stats.stopped_by = sig.name or "signal"
            except BrokenPipeError:
                stats.stopped_by = "closed output"
    finally:
        sink.close()
    stats.contact_samples = contacts + monitor.contact_samples
    return stats
