"""A child process for the exit tests of the asyncio clients: opens FAMILY's async client on PORT and lets
the script end in STATE.

    python _async_exit.py FAMILY PORT STATE

``idle``: the client reads a position inside ``async with``, waits, and the block closes it.
``mid-call``: a read is in flight (a task nobody awaits) when ``asyncio.run`` ends; the client is never
closed by the script (the exit handler closes it).
``mid-move``: a long move is in flight (a task nobody awaits) when the ``async with`` block ends and
``asyncio.run`` with it.
``mid-move-open``: a long move is in flight on a loop that is never closed, by a client never closed, when
the script ends: only the exit handler can stop it.
``abandoned``: a long move is in flight on a client opened with ``await open()`` and never closed when
``asyncio.run`` ends (which cancels the move); the client is then garbage, collected: only the exit handler
can end its session.
``in-callback``: as ``idle``, but the library's delivery thread lingers in the close's callback after
handing the outcome to the loop (without the GIL, as in the socket write of ``call_soon_threadsafe``)
until the script has ended and the exit handlers run, and a little longer: it is inside a callback when
the interpreter would finalise.

Prints ``moving`` once the device reports the move, ``end`` as the script's last line.
"""

import asyncio
import sys

import motionlink as ml

family, port, state = sys.argv[1], sys.argv[2], sys.argv[3]


def client():
    if family == "scu":
        return ml.AsyncScu(port)
    if family == "powercube":
        return ml.AsyncPowerCube(port)
    return ml.AsyncCompax(port)


async def read(c):
    return await (c.position(1) if family == "scu" else c.position())


def long_move(c):
    if family == "scu":
        return c.move_to(1, 800, speed=5)
    if family == "powercube":
        return c.move_to(3.0, velocity=0.1)
    return c.move_to(100000.0, speed_percent=1)


async def until_moving(c, move):
    """Waits until the position has changed (the device moves), or the move's task has ended."""
    first = (await read(c)).to_dict()
    while not move.done():
        await asyncio.sleep(0.02)
        if (await read(c)).to_dict() != first:
            print("moving", flush=True)
            return
    move.result()


closing = False


async def idle():
    global closing
    async with client() as c:
        print(await read(c), flush=True)
        await asyncio.sleep(0.2)
        closing = True


async def mid_call():
    c = await client().open()
    asyncio.create_task(read(c))
    await asyncio.sleep(0)


async def mid_move():
    async with client() as c:
        move = asyncio.create_task(long_move(c))
        await until_moving(c, move)


async def abandoned():
    c = await client().open()
    move = asyncio.create_task(long_move(c))
    await until_moving(c, move)


if state == "idle":
    asyncio.run(idle())
elif state == "in-callback":
    import atexit
    import threading
    import time

    # Registered after motionlink's own exit handler, so it runs before it (atexit is last in, first out).
    exiting = threading.Event()
    atexit.register(exiting.set)
    handed = asyncio.BaseEventLoop.call_soon_threadsafe

    def lingering(loop, *args, **kwargs):
        handle = handed(loop, *args, **kwargs)
        if closing and isinstance(threading.current_thread(), threading._DummyThread):  # the library's thread
            exiting.wait(10)
            time.sleep(0.1)
        return handle

    asyncio.BaseEventLoop.call_soon_threadsafe = lingering
    asyncio.run(idle())
elif state == "mid-call":
    asyncio.run(mid_call())
elif state == "mid-move":
    asyncio.run(mid_move())
elif state == "abandoned":
    import gc

    asyncio.run(abandoned())
    gc.collect()
elif state == "mid-move-open":
    loop = asyncio.new_event_loop()
    c = loop.run_until_complete(client().open())
    move = loop.create_task(long_move(c))
    loop.run_until_complete(until_moving(c, move))
else:
    sys.exit(f"unknown state {state!r}")
print("end", flush=True)
