"""Per-call overhead of a position read through Python, against the in-process emulator.

    python python/bench/read_position.py [--calls N] [--rounds R]

Prints the time per ``PowerCube.position()`` call (the typed result included), per raw native call, and
per read of the same loop in Rust with no Python in between; the difference is what Python adds. The
best of R rounds is reported (the machine is shared). Target: Python's overhead under 20 us per call.
"""

from __future__ import annotations

import argparse
import time

import motionlink


def best_per_call(fn, calls: int, rounds: int) -> float:
    best = float("inf")
    for _ in range(rounds):
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        best = min(best, (time.perf_counter() - start) / calls)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=2000)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    with motionlink.Emulator("powercube") as emu, motionlink.PowerCube(emu) as cube:
        cube.position()  # the module's kind is read once, then kept
        native = cube._native
        typed = best_per_call(cube.position, args.calls, args.rounds)
        raw = best_per_call(lambda: native.position(None), args.calls, args.rounds)
        rust = min(native._bench_native_reads(args.calls, None) / args.calls for _ in range(args.rounds))
    us = 1e6
    print(f"position read, Rust loop (no Python):     {rust * us:8.2f} us/call")
    print(f"position read, native call from Python:   {raw * us:8.2f} us/call")
    print(f"position read, PowerCube.position():      {typed * us:8.2f} us/call")
    print(f"overhead of Python (typed - Rust):        {(typed - rust) * us:8.2f} us/call  (target < 20 us)")


if __name__ == "__main__":
    main()
