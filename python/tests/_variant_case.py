"""A child process of test_variants.py: runs one family's core operations against one emulated firmware and
prints what each did, one JSON object a line, as soon as it is done (so that a case that hangs shows the
last operation that ended):

    python _variant_case.py '{"family": "scu", "variant": ["no-groups"], "client": "sync", "serve": null,
                              "can": false, "mode": 0}'

Each line is ``{"op", "ok": true, "type", "value", "elapsed_s"}`` (``value`` the result's ``to_dict()``,
``type`` its class) or ``{"op", "ok": false, "error", "kind", "message", "elapsed_s"}`` for a
:class:`motionlink.MotionlinkError`. Any other exception is a defect: it ends the process with its
traceback. The operations and their arguments are here; what each must give is in test_variants.py.
"""

from __future__ import annotations

import asyncio
import json
import sys
import time
from typing import Any, Awaitable, Callable, Dict, Optional

import motionlink as ml

#: Fast SCU actuators (2000 counts/s, 30 ms ramps): a move of a few hundred counts takes a fraction of a second.
SCU_FAST = (
    "[[actuator]]\ncounts_per_second_at_full_speed = 2000.0\nramp_ms = 30\n"
    "[[actuator]]\ncounts_per_second_at_full_speed = 2000.0\nramp_ms = 30\n"
)
#: COMPAX drives at 115200 baud (the in-process bus is paced at the baud rate).
COMPAX_BAUD = 115_200
#: How long a COMPAX or PowerCube client waits for a reply: absent addresses of a scan each cost this.
REPLY_TIMEOUT_MS = 50
#: Every wait for the end of a motion is bounded by the client too.
MOTION_TIMEOUT_S = 20.0


def plain(value: Any) -> Any:
    if isinstance(value, ml.records.Record):
        return value.to_dict()
    if isinstance(value, list):
        return [plain(v) for v in value]
    if isinstance(value, (ml.Scu, ml.PowerCube, ml.Compax, ml.AsyncScu, ml.AsyncPowerCube, ml.AsyncCompax)):
        return {"port": value.port}
    return value


def report(op: str, started: float, outcome: Dict[str, Any]) -> None:
    line = {"op": op, **outcome, "elapsed_s": round(time.monotonic() - started, 3)}
    print(json.dumps(line), flush=True)


def ok(value: Any) -> Dict[str, Any]:
    kind = type(value[0] if isinstance(value, list) and value else value).__name__
    return {"ok": True, "type": kind, "value": plain(value)}


def failed(e: ml.MotionlinkError) -> Dict[str, Any]:
    return {"ok": False, "error": type(e).__name__, "kind": e.kind, "message": str(e)}


def run(op: str, call: Callable[[], Any]) -> Any:
    started = time.monotonic()
    try:
        value = call()
    except ml.MotionlinkError as e:
        report(op, started, failed(e))
        return None
    report(op, started, ok(value))
    return value


async def run_async(op: str, call: Callable[[], Awaitable[Any]]) -> Any:
    started = time.monotonic()
    try:
        value = await call()
    except ml.MotionlinkError as e:
        report(op, started, failed(e))
        return None
    report(op, started, ok(value))
    return value


def emulator(case: Dict[str, Any]) -> ml.Emulator:
    family, variant = case["family"], case["variant"] or None
    serve = case.get("serve")
    if family == "scu":
        return ml.Emulator("scu", preset="scp11", config=SCU_FAST, variant=variant, serve=serve)
    if family == "powercube":
        return ml.Emulator("powercube", variant=variant, serve=serve, can=case.get("can", False))
    return ml.Emulator(
        "compax", drives=[1, 3], mode=case.get("mode", 0), baud=COMPAX_BAUD, params={"P12": 0.0},
        variant=variant, serve=serve,
    )


# ------------------------------------------------------------------------------------------------ blocking


def scu_sync(port: Any) -> None:
    c: Optional[ml.Scu] = run("open", lambda: ml.Scu(port, functions="scp11"))
    if c is None:
        return
    run("info", c.info)
    run("get_group", lambda: c.get("actual_positions"))
    run("get_entry", lambda: c.get("actual_position_a1"))
    run("set", lambda: c.set("remote_speed_f2", 60))
    run("move_with_speed", lambda: c.move_to(1, 400, speed=80))
    run("move_without_speed", lambda: c.move_to(2, 300))
    run("home", lambda: c.run(1, "in"))
    run("stop", lambda: c.stop(1))
    run("started", c.started)
    run("watch", lambda: list(c.watch(interval_ms=50, count=3)))
    run("move_outside_stroke", lambda: c.move_to(1, 900))
    run("position_after", lambda: c.position(1))
    run("close", c.close)
    # A second session that asks for a tighter in-position tolerance than the default 5 counts.
    strict: Optional[ml.Scu] = run("open_strict", lambda: ml.Scu(port, functions="scp11", tolerance_counts=2))
    if strict is not None:
        run("strict_move_out", lambda: strict.move_to(1, 200))
        run("strict_move_in_end", lambda: strict.move_to(1, 0))
        run("close_strict", strict.close)


def powercube_sync(port: Any) -> None:
    c: Optional[ml.PowerCube] = run("open", lambda: ml.PowerCube(port, timeout_ms=REPLY_TIMEOUT_MS))
    if c is None:
        return
    run("scan", c.scan)
    run("get", lambda: c.get("ActPos"))
    run("set", lambda: c.set("TargetVel", 0.8))
    run("home", lambda: c.home(timeout_s=MOTION_TIMEOUT_S))
    run("move_with_speed", lambda: c.move_to(0.3, velocity=0.7, acceleration=1.5, timeout_s=MOTION_TIMEOUT_S))
    run("move_without_speed", lambda: c.move_to(0.1, timeout_s=MOTION_TIMEOUT_S))
    run("watch", lambda: list(c.watch(interval_ms=20, count=3)))
    run("move_outside_limit", lambda: c.move_to(100.0, timeout_s=MOTION_TIMEOUT_S))
    run("stop", c.stop)
    run("state_after_stop", c.state)
    run("move_halted", lambda: c.move_to(0.2, timeout_s=MOTION_TIMEOUT_S))
    run("reset", c.reset)
    run("move_after_reset", lambda: c.move_to(0.2, timeout_s=MOTION_TIMEOUT_S))
    run("started", c.started)
    run("close", c.close)


def compax_sync(port: Any, mode: int) -> None:
    c: Optional[ml.Compax] = run(
        "open", lambda: ml.Compax(port, mode=mode, baud=COMPAX_BAUD, timeout_ms=REPLY_TIMEOUT_MS)
    )
    if c is None:
        return
    run("scan", c.scan)
    run("status", lambda: c.status(["S1", "S16", "S17"]))
    run("get", lambda: c.get("P12"))
    run("set", lambda: c.set("P12", 2.5))
    run("home", lambda: c.home(timeout_s=MOTION_TIMEOUT_S))
    run("move_with_speed", lambda: c.move_to(20.0, speed_percent=100, timeout_s=MOTION_TIMEOUT_S))
    run("move_without_speed", lambda: c.move_to(distance=-5.0, timeout_s=MOTION_TIMEOUT_S))
    run("watch", lambda: list(c.watch(interval_ms=20, count=3)))
    run("move_outside_limits", lambda: c.move_to(50.0, max_units=30.0, timeout_s=MOTION_TIMEOUT_S))
    run("stop", c.stop)
    run("switch_off", lambda: c.output(0, 0))
    run("move_switched_off", lambda: c.move_to(10.0, timeout_s=MOTION_TIMEOUT_S))
    run("switch_on", lambda: c.output(0, 1))
    run("move_after_switch_on", lambda: c.move_to(10.0, timeout_s=MOTION_TIMEOUT_S))
    run("position_after", c.position)
    run("started", c.started)
    run("close", c.close)


# --------------------------------------------------------------------------------------------------- async


async def scu_async(port: Any) -> None:
    c: Optional[ml.AsyncScu] = await run_async("open", lambda: ml.AsyncScu(port, functions="scp11").open())
    if c is None:
        return
    await run_async("position", lambda: c.position(1))
    await run_async("move_with_speed", lambda: c.move_to(1, 400, speed=80))
    await run_async("move_without_speed", lambda: c.move_to(2, 300))
    await run_async("home", lambda: c.run(1, "in"))
    await run_async("stop", lambda: c.stop(1))
    await run_async("move_outside_stroke", lambda: c.move_to(1, 900))
    await run_async("close", c.aclose)


async def powercube_async(port: Any) -> None:
    c: Optional[ml.AsyncPowerCube] = await run_async(
        "open", lambda: ml.AsyncPowerCube(port, timeout_ms=REPLY_TIMEOUT_MS).open()
    )
    if c is None:
        return
    await run_async("position", c.position)
    await run_async("home", lambda: c.home(timeout_s=MOTION_TIMEOUT_S))
    await run_async(
        "move_with_speed", lambda: c.move_to(0.3, velocity=0.7, acceleration=1.5, timeout_s=MOTION_TIMEOUT_S)
    )
    await run_async("move_without_speed", lambda: c.move_to(0.1, timeout_s=MOTION_TIMEOUT_S))
    await run_async("wait", lambda: c.wait(timeout_s=MOTION_TIMEOUT_S))
    await run_async("move_outside_limit", lambda: c.move_to(100.0, timeout_s=MOTION_TIMEOUT_S))
    await run_async("stop", c.stop)
    await run_async("state_after_stop", c.state)
    await run_async("close", c.aclose)


async def compax_async(port: Any, mode: int) -> None:
    c: Optional[ml.AsyncCompax] = await run_async(
        "open", lambda: ml.AsyncCompax(port, mode=mode, baud=COMPAX_BAUD, timeout_ms=REPLY_TIMEOUT_MS).open()
    )
    if c is None:
        return
    await run_async("position", c.position)
    await run_async("home", lambda: c.home(timeout_s=MOTION_TIMEOUT_S))
    await run_async("move_with_speed", lambda: c.move_to(20.0, speed_percent=100, timeout_s=MOTION_TIMEOUT_S))
    await run_async("move_without_speed", lambda: c.move_to(distance=-5.0, timeout_s=MOTION_TIMEOUT_S))
    await run_async("wait", lambda: c.wait(timeout_s=MOTION_TIMEOUT_S))
    await run_async("move_outside_limits", lambda: c.move_to(50.0, max_units=30.0, timeout_s=MOTION_TIMEOUT_S))
    await run_async("stop", c.stop)
    await run_async("close", c.aclose)


def main(case: Dict[str, Any]) -> None:
    family, mode = case["family"], case.get("mode", 0)
    with emulator(case) as emu:
        port: Any = emu.port if case.get("serve") else emu
        if case["client"] == "async":
            steps: Dict[str, Callable[[], Awaitable[None]]] = {
                "scu": lambda: scu_async(port),
                "powercube": lambda: powercube_async(port),
                "compax": lambda: compax_async(port, mode),
            }
            asyncio.run(steps[family]())
        else:
            calls: Dict[str, Callable[[], None]] = {
                "scu": lambda: scu_sync(port),
                "powercube": lambda: powercube_sync(port),
                "compax": lambda: compax_sync(port, mode),
            }
            calls[family]()


if __name__ == "__main__":
    main(json.loads(sys.argv[1]))
