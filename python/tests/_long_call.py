"""A child process for the Ctrl-C tests of calls other than a move: opens a client of FAMILY on PORT,
prints ``ready`` once it is inside the long call OP, and when OP raises KeyboardInterrupt prints ``interrupted
<unix time>`` (then leaves the client's block, closing it) and exits with 130.

    python _long_call.py FAMILY PORT OP      OP: scan | home | wait | run
"""

import sys
import threading
import time

import motionlink as ml



def _run(fn):
    try:
        fn()
    except BaseException:  # noqa: BLE001 - the move is cancelled by the interrupt; the parent looks at events
        pass


def _announce_when_inside(name):
    """Prints ``ready`` once the main thread is inside the client's method ``name`` (its Python frame is
    the method's, waiting in the native call), so that a signal sent then lands in that call."""
    main = threading.main_thread().ident
    while True:
        frame = sys._current_frames().get(main)
        if frame is not None and frame.f_code.co_name == name and "motionlink" in frame.f_code.co_filename:
            print("ready", flush=True)
            return
        time.sleep(0.002)


def _moving():
    """True once the device reports the move (not only once the session sent it)."""
    if family == "powercube":
        return "STATE_MOTION" in client.state().flags
    return "COMMAND_ACTIVE" in client.status(["S17"])[0].value.flags


family, port, op = sys.argv[1], sys.argv[2], sys.argv[3]
if family == "powercube":
    client = ml.PowerCube(port)
    mover = lambda: client.move_to(3.0, velocity=0.1)  # noqa: E731 - 30 s of motion
elif family == "scu":
    client = ml.Scu(port)
    mover = lambda: client.move_to(1, 800, speed=5)  # noqa: E731
else:
    client = ml.Compax(port)
    mover = lambda: client.move_to(100000.0, speed_percent=1)  # noqa: E731

try:
    with client:
        if op == "wait":
            # A move in another thread; `wait` in the main thread once the device reports the motion.
            threading.Thread(target=lambda: _run(mover), daemon=True).start()
            while not _moving():
                time.sleep(0.005)
        threading.Thread(target=_announce_when_inside, args=(op,), daemon=True).start()
        try:
            if op == "scan":
                client.scan()
            elif op == "home":
                client.home()
            elif op == "wait":
                client.wait()
            else:
                client.run(1, "out")
        except KeyboardInterrupt:
            # When the call raised it (leaving the block then closes the client, which takes its time).
            print(f"interrupted {time.time():.6f}", flush=True)
            if op == "scan":
                # The scan ended on its thread as well: the next call does not queue behind what was left of it.
                started = time.time()
                client.state() if family == "powercube" else client.position()
                print(f"next call {time.time() - started:.6f}", flush=True)
            raise
except KeyboardInterrupt:
    sys.exit(130)
print("ended without an interrupt", flush=True)

