"""A child process that serves an emulator on a TCP port, so that its clock (and the time of its
configured ``[[error]]``s, counted from power-on) starts with this process:

    python _serve.py FAMILY CONFIG_TOML

prints the port URL, then serves until its stdin is closed.
"""

import sys

import motionlink

with motionlink.Emulator(sys.argv[1], serve="tcp", config=sys.argv[2]) as emu:
    print(emu.port, flush=True)
    sys.stdin.read()
