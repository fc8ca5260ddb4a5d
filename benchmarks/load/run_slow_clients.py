#!/usr/bin/env python3
"""Slow clients against the e-stop (docs/SAFETY.md, "The e-stop under load").

Starts fesbench-server on a loopback port with a temporary database, opens
CLIENTS connections that each send a request head one byte per second (a
"slowloris" crowd; a connection the server closes is opened again), and
meanwhile presses the e-stop (POST /api/v1/bench/estop with the admin token,
each on a new connection) every PERIOD seconds. Prints how many presses were
answered 200 and their latency (p50, p99, max), and how many slow
connections the server closed (408 at the head deadline, or to make room).

    benchmarks/load/run_slow_clients.py [--clients N] [--seconds S] [--server BIN]
"""

import argparse
import os
import pathlib
import re
import select
import socket
import subprocess
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]
SLOW_HEAD = b"POST /api/v1/subjects HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"


def start_server(binary, work):
    out = open(os.path.join(work, "server.out"), "w+")
    proc = subprocess.Popen(
        [binary, "--bind", "127.0.0.1", "--port", "0", "--db", os.path.join(work, "fesbench.db"),
         "--data-dir", work, "--time-scale", "1", "--dds-transport", "off"],
        stdout=out, stderr=subprocess.STDOUT)
    for _ in range(100):
        time.sleep(0.1)
        out.seek(0)
        found = re.search(r"listening on http://127\.0\.0\.1:(\d+)", out.read())
        if found:
            token = open(os.path.join(work, "admin.token")).read().strip()
            return proc, int(found.group(1)), token
    proc.kill()
    raise SystemExit("the server did not start")


def press_estop(port, token):
    """Latency in ms of one e-stop answered 200, or None."""
    start = time.monotonic()
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            s.sendall(b"POST /api/v1/bench/estop HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " +
                      token.encode() + b"\r\nContent-Length: 0\r\nConnection: close\r\n\r\n")
            answer = s.recv(64)
    except OSError:
        return None
    return (time.monotonic() - start) * 1e3 if answer.startswith(b"HTTP/1.1 200") else None


def percentile(values, fraction):
    return values[min(len(values) - 1, int(len(values) * fraction))]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clients", type=int, default=400)
    parser.add_argument("--seconds", type=float, default=20)
    parser.add_argument("--period", type=float, default=0.25, help="seconds between presses")
    parser.add_argument("--server", default=str(ROOT / "build" / "server" / "fesbench-server"))
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as work:
        proc, port, token = start_server(args.server, work)
        slow = {}  # socket -> bytes of SLOW_HEAD sent
        closed_by_server = 0
        latencies, presses = [], 0
        end = time.monotonic() + args.seconds
        next_byte = next_press = time.monotonic()
        try:
            while time.monotonic() < end:
                while len(slow) < args.clients:
                    s = socket.socket()
                    s.setblocking(False)
                    s.connect_ex(("127.0.0.1", port))
                    slow[s] = 0
                now = time.monotonic()
                if now >= next_byte:  # one byte per connection per second
                    next_byte = now + 1.0
                    for s in list(slow):
                        try:
                            s.send(SLOW_HEAD[slow[s] % len(SLOW_HEAD):][:1])
                            slow[s] += 1
                        except OSError:
                            closed_by_server += 1
                            s.close()
                            del slow[s]
                if now >= next_press:
                    next_press = now + args.period
                    presses += 1
                    ms = press_estop(port, token)
                    if ms is not None:
                        latencies.append(ms)
                readable, _, _ = select.select(list(slow), [], [], 0.02)
                for s in readable:  # an answer (408) or a close: open another
                    closed_by_server += 1
                    s.close()
                    del slow[s]
        finally:
            for s in slow:
                s.close()
            proc.terminate()
            proc.wait()
    latencies.sort()
    print(f"{args.clients} slow clients, {args.seconds:.0f} s: e-stop answered 200 "
          f"{len(latencies)}/{presses}", end="")
    if latencies:
        print(f"; p50 {percentile(latencies, 0.5):.1f} ms, p99 {percentile(latencies, 0.99):.1f} ms, "
              f"max {latencies[-1]:.1f} ms", end="")
    print(f"; slow connections closed by the server: {closed_by_server}")


if __name__ == "__main__":
    main()
