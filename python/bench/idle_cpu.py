"""The CPU an open session costs while it does nothing, per family.

    python python/bench/idle_cpu.py [--seconds S] [--bin PATH]

For each family, starts `motionlink sim <family> --tcp 127.0.0.1:0` (a separate process), opens a client on
it (the SCU's session keeps the unit's watchdog fed with an RC every 200 ms; PowerCube and COMPAX sessions
send nothing while idle), waits a second, then measures this process's CPU time over S seconds (default 10)
of an idle session, as a share of one core. The target is under 1 %.

The binary is `--bin`, else `MOTIONLINK_BIN`, else `motionlink` on the PATH.
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--bin", default=os.environ.get("MOTIONLINK_BIN") or shutil.which("motionlink"))
    args = ap.parse_args()
    if not args.bin:
        sys.exit("no motionlink binary: give --bin or set MOTIONLINK_BIN")
    for family, client in (("scu", motionlink.Scu), ("powercube", motionlink.PowerCube), ("compax", motionlink.Compax)):
        sim = subprocess.Popen([args.bin, "sim", family, "--tcp", "127.0.0.1:0"], stdout=subprocess.PIPE, text=True)
        try:
            assert sim.stdout is not None
            line = sim.stdout.readline()
            found = re.search(r"(tcp://[0-9.:]+)", line)
            if not found:
                sys.exit(f"the {family} emulator did not name its address: {line!r}")
            with client(found.group(1)):
                time.sleep(1.0)
                cpu0, wall0 = time.process_time(), time.monotonic()
                time.sleep(args.seconds)
                cpu, wall = time.process_time() - cpu0, time.monotonic() - wall0
        finally:
            sim.terminate()
            sim.wait()
        share = 100 * cpu / wall
        verdict = "met" if share < 1 else "NOT met"
        print(f"{family:9}: {cpu * 1e3:7.1f} ms of CPU in {wall:.1f} s idle = {share:.3f} % of a core (target: under 1 %: {verdict})")


if __name__ == "__main__":
    main()
