"""A child process for the Ctrl-C and exit tests: opens a client of FAMILY on PORT and starts a long move.

    python _long_move.py FAMILY PORT [wait|term|thread-exit|thread-sleep|thread-return]

``wait``: the move runs in the main thread (Ctrl-C lands in it); ``term``: the same with a SIGTERM handler
that raises SystemExit. ``thread-exit``: the move runs in a
daemon thread and the main thread returns at once without closing the client (the exit handler must stop
the motion). ``thread-sleep``: the move runs in a thread that is no daemon while the main thread sleeps
(Ctrl-C lands in the sleep; Python then waits for that thread). ``thread-return``: the same, and the main
thread returns at once (Python waits for that thread, whose move goes on).
"""

import signal
import sys
import threading
import time

import motionlink as ml

family, port, how = sys.argv[1], sys.argv[2], sys.argv[3]
if family == "powercube":
    client = ml.PowerCube(port)
    op = lambda: client.move_to(3.0, velocity=0.1)  # noqa: E731 - 30 s of motion
elif family == "scu":
    client = ml.Scu(port)
    op = lambda: client.move_to(1, 800, speed=5)  # noqa: E731
else:
    client = ml.Compax(port)
    op = lambda: client.move_to(100000.0, speed_percent=1)  # noqa: E731

if how == "term":
    # The README's advice: make SIGTERM an exception, so that it stops the motion as Ctrl-C does.
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))
    how = "wait"
if how == "wait":
    with client:
        print("moving", flush=True)
        op()
else:
    threading.Thread(target=op, daemon=how == "thread-exit").start()
    print("moving", flush=True)
    if how != "thread-return":
        time.sleep(0.2 if how == "thread-exit" else 60)
