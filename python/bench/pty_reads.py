"""Position reads of one PowerCube module over a pseudo-terminal, against a separate emulator process.

    python python/bench/pty_reads.py [--reads N] [--rounds R] [--bin PATH] [--floor PATH]

The set-up of the vendor's figures (libm5api, the C++ library: 15.9 k reads/s at 25 us of CPU per read over
one pty against one `motionlink sim powercube --pty` process): this script starts that process, opens the
pty with `motionlink.PowerCube` (RS232 framing, module 1, no watchdog) and reads ActPos N times, R rounds.
It prints, for the best round, the reads per second and the CPU time of this process per read (the Python
call, the native client and the line's I/O; the emulator's own CPU is the other process's), and the same
loop in Rust through the native module with no Python in between; then as many streamed velocity setpoints
(`PowerCube.setpoint("fvel_ack", ...)`, a small velocity each way in turn, the module homed first: each
call one exchange, its acknowledge carrying the position), as a control loop sends them.

The binary is `--bin`, else `MOTIONLINK_BIN`, else `motionlink` on the PATH. With `--floor`, the path of
the `pty_floor` example (`cargo build --release -p motionlink-powercube --example pty_floor`, then
`target/release/examples/pty_floor`), the same reads are then made over the same pty with nothing but the
line's I/O: the floor that the kernel and the emulator set on this machine.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import time

import motionlink


def emulator(binary: str) -> tuple[subprocess.Popen, str]:
    """Starts `motionlink sim powercube --pty` and returns it with the pty's path."""
    proc = subprocess.Popen([binary, "sim", "powercube", "--pty"], stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    line = proc.stdout.readline()
    found = re.search(r"(/dev/pts/\d+)", line)
    if not found:
        proc.kill()
        sys.exit(f"the emulator did not name its pty: {line!r}")
    return proc, found.group(1)


def best_round(read, reads: int, rounds: int) -> tuple[float, float]:
    """The best round's wall time and this process's CPU time, each per read, in seconds."""
    best = (float("inf"), float("inf"))
    for _ in range(rounds):
        wall0, cpu0 = time.perf_counter(), time.process_time()
        read(reads)
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        best = min(best, (wall / reads, cpu / reads))
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reads", type=int, default=2000)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--bin", default=os.environ.get("MOTIONLINK_BIN") or shutil.which("motionlink"))
    ap.add_argument("--floor", help="the pty_floor example's binary: also measure the floor")
    args = ap.parse_args()
    if not args.bin:
        sys.exit("no motionlink binary: give --bin or set MOTIONLINK_BIN")
    proc, pty = emulator(args.bin)
    try:
        with motionlink.PowerCube(pty, module=1, watchdog=False) as cube:
            cube.position()  # the module's kind is read once, then kept
            native = cube._native

            def python_loop(n: int) -> None:
                for _ in range(n):
                    cube.position()

            def rust_loop(n: int) -> None:
                native._bench_native_reads(n, None)

            def setpoint_loop(n: int) -> None:
                for i in range(n):
                    cube.setpoint("fvel_ack", 0.01 if i % 2 else -0.01)

            py_wall, py_cpu = best_round(python_loop, args.reads, args.rounds)
            rs_wall, rs_cpu = best_round(rust_loop, args.reads, args.rounds)
            cube.home()
            cube.setpoint("fvel_ack", 0.0)  # the first: limits read, readiness checked
            sp_wall, sp_cpu = best_round(setpoint_loop, args.reads, args.rounds)
            cube.setpoint("fvel_ack", 0.0)
        # The client has closed the pty (it holds it exclusively): the floor's reads over the same one.
        floor = None
        if args.floor:
            done = subprocess.run(
                [args.floor, pty, str(args.reads), str(args.rounds)], capture_output=True, text=True, check=True
            )
            floor = done.stdout.strip().splitlines()[-1]
    finally:
        proc.terminate()
        proc.wait()
    print(f"{args.reads} ActPos reads over {pty}, best of {args.rounds} rounds")
    print(f"Rust loop (native module):  {1 / rs_wall / 1e3:6.1f} k reads/s, {rs_cpu * 1e6:6.1f} us CPU per read")
    print(f"PowerCube.position():       {1 / py_wall / 1e3:6.1f} k reads/s, {py_cpu * 1e6:6.1f} us CPU per read")
    print(f"Python vs Rust rate:        {py_wall / rs_wall * 100 - 100:+6.1f} % time per read")
    print(f"PowerCube.setpoint(FVEL_ACK): {1 / sp_wall / 1e3:6.1f} k setpoints/s, {sp_cpu * 1e6:6.1f} us CPU each")
    if floor:
        print(f"floor (the line's I/O only):  {floor}")
    print("libm5api (vendor, C++):       15.9 k reads/s,   25.0 us CPU per read")


if __name__ == "__main__":
    main()
