"""Every exception class of motionlink.errors, raised by a real failure against the emulators (or a
misbehaving peer), with the attributes the command line's JSON names."""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
from typing import Callable, Iterator

import pytest

import motionlink
from motionlink import errors


def test_the_hierarchy_is_the_issue_s() -> None:
    for cls in (
        errors.DeviceRefused,
        errors.DeviceError,
        errors.TransportError,
        errors.UsageError,
        errors.Cancelled,
    ):
        assert issubclass(cls, errors.MotionlinkError)
    for cls in (errors.TimeoutError, errors.Disconnected, errors.CorruptFrame):
        assert issubclass(cls, errors.TransportError)
    assert issubclass(errors.UsageError, ValueError)
    assert motionlink.TimeoutError is errors.TimeoutError


def test_usage_error_is_a_value_error_and_nothing_is_sent(cube: motionlink.PowerCube) -> None:
    with pytest.raises(ValueError) as e:
        cube.get("NoSuchParameter")
    assert isinstance(e.value, motionlink.UsageError)
    assert (e.value.kind, e.value.exit_code, e.value.family) == ("usage", 2, "powercube")
    assert e.value.to_dict() == {"kind": "usage", "message": str(e.value), "exit_code": 2}
    with pytest.raises(motionlink.UsageError, match=r"outside MinPos\.\.MaxPos"):
        cube.move_to(10.0)
    with pytest.raises(motionlink.UsageError):
        motionlink.PowerCube("sim", module=40)
    with pytest.raises(motionlink.UsageError):
        motionlink.Emulator("scu", modules=[1])


def test_device_error_carries_the_code_and_named_bits(cube: motionlink.PowerCube) -> None:
    cube.stop()
    with pytest.raises(motionlink.DeviceError) as e:
        cube.move_to(0.1)
    err = e.value
    assert (err.kind, err.exit_code) == ("device", 1)
    assert err.code is not None and err.code & 0x4
    assert {"bit": 2, "name": "STATE_HALTED"}.items() <= err.bits[0].items()
    assert err.to_dict()["bits"] == err.bits


def test_device_refused_is_the_drive_s_exx(compax: motionlink.Compax) -> None:
    with pytest.raises(motionlink.DeviceRefused) as e:
        compax.get("P250")
    assert (e.value.kind, e.value.exit_code, e.value.code) == ("refused", 1, 90)


def test_timeout_error_for_a_module_that_does_not_answer(cube: motionlink.PowerCube) -> None:
    with pytest.raises(motionlink.TimeoutError) as e:
        cube.position(5)
    assert (e.value.kind, e.value.exit_code) == ("timeout", 3)
    assert isinstance(e.value, motionlink.TransportError)


def test_disconnected_when_the_peer_goes_away() -> None:
    emu = motionlink.Emulator("powercube", serve="tcp")
    with motionlink.PowerCube(emu.port) as c:
        c.position()
        emu.close()
        with pytest.raises(motionlink.Disconnected) as e:
            c.position()
        assert e.value.kind == "disconnected"


def test_transport_error_for_a_port_that_cannot_be_opened() -> None:
    with pytest.raises(motionlink.TransportError) as e:
        motionlink.PowerCube("/dev/motionlink-no-such-port")
    assert type(e.value) is motionlink.TransportError and e.value.kind == "io"


Replies = Callable[[bytes], bytes]


@pytest.fixture
def proxy() -> Iterator[Callable[[str, Replies], str]]:
    """A TCP proxy in front of an emulator that passes each chunk of the replies through a function."""
    servers = []

    def start(upstream: str, replies: Replies) -> str:
        host, port = upstream[len("tcp://") :].rsplit(":", 1)
        srv = socket.socket()
        srv.bind(("127.0.0.1", 0))
        srv.listen(1)
        servers.append(srv)

        def run() -> None:
            conn, _ = srv.accept()
            up = socket.create_connection((host, int(port)))

            def down() -> None:
                while data := up.recv(4096):
                    if passed := replies(data):
                        conn.sendall(passed)

            threading.Thread(target=down, daemon=True).start()
            while data := conn.recv(4096):
                up.sendall(data)
            up.close()

        threading.Thread(target=run, daemon=True).start()
        return f"tcp://127.0.0.1:{srv.getsockname()[1]}"

    yield start
    for s in servers:
        s.close()


@pytest.mark.parametrize("family", ["powercube", "compax"])
def test_corrupt_frame_for_mangled_replies(family: str, proxy: Callable[[str, Replies], str]) -> None:
    with motionlink.Emulator(family, serve="tcp") as emu:
        # The second byte of every reply changed.
        port = proxy(emu.port, lambda data: data[:1] + b"A" + data[2:] if len(data) > 2 else data)
        with pytest.raises(motionlink.CorruptFrame) as e:
            client = motionlink.PowerCube(port) if family == "powercube" else motionlink.Compax(port)
            with client:
                client.position()
        assert (e.value.kind, e.value.exit_code) == ("corrupt", 3)


def test_cancelled_for_a_move_whose_client_is_closed(
    cube: motionlink.PowerCube, powercube_emulator: motionlink.Emulator
) -> None:
    outcome = []

    def move() -> None:
        try:
            cube.move_to(3.0, velocity=0.1)
        except motionlink.MotionlinkError as e:
            outcome.append(e)

    t = threading.Thread(target=move)
    t.start()
    powercube_emulator.wait_event(lambda s: "motion started" in s)
    cube.close()
    t.join(5)
    assert isinstance(outcome[0], motionlink.Cancelled)
    assert "halt" in str(outcome[0]) and outcome[0].kind == "cancelled"
    with pytest.raises(motionlink.UsageError, match="closed"):
        cube.position()


def test_a_stop_the_module_does_not_confirm_says_so_as_data(proxy: Callable[[str, Replies], str]) -> None:
    """A move whose client is closed while the line is silent: the halt is not acknowledged, so the error
    is the line's (a TimeoutError, not Cancelled) and ``stop_unconfirmed`` says the axis may still move."""
    silent = threading.Event()
    with motionlink.Emulator("powercube", serve="tcp") as emu:
        cube = motionlink.PowerCube(proxy(emu.port, lambda data: b"" if silent.is_set() else data))
        cube.home()
        emu.take_events()  # the home's own "motion started" is not the move's
        outcome = []

        def move() -> None:
            try:
                cube.move_to(2.0, velocity=0.2)
            except motionlink.MotionlinkError as e:
                outcome.append(e)

        t = threading.Thread(target=move)
        t.start()
        emu.wait_event(lambda s: "motion started" in s)
        silent.set()
        # The close says what it could not do either (the watchdog left online, or its own stop); the
        # move's error is the one under test.
        with contextlib.suppress(motionlink.MotionlinkError):
            cube.close()
        t.join(10)
    err = outcome[0]
    assert isinstance(err, motionlink.TimeoutError) and err.stop_unconfirmed, err
    assert "may still be moving" in str(err)
    assert err.to_dict() == {"kind": "timeout", "message": str(err), "exit_code": 3, "stop_unconfirmed": True}


@pytest.mark.parametrize("face", ["sync", "async"])
def test_a_with_block_whose_stop_was_not_confirmed_raises_that_error_with_the_close_as_a_note(
    face: str, proxy: Callable[[str, Replies], str]
) -> None:
    """The move's error says the stop was not confirmed; the close at the end of the block fails too: the
    move's error is what the block raises, the close's is a note on it (not a second exception)."""
    silent = threading.Event()
    with motionlink.Emulator("powercube", serve="tcp") as emu:
        port = proxy(emu.port, lambda data: b"" if silent.is_set() else data)

        def cut_under_the_move() -> None:
            emu.take_events()
            threading.Thread(target=lambda: (emu.wait_event(lambda s: "motion started" in s), silent.set())).start()

        async def in_async_with() -> None:
            async with motionlink.AsyncPowerCube(port) as cube:
                await cube.home()
                cut_under_the_move()
                await cube.move_to(2.0, velocity=0.2)

        with pytest.raises(motionlink.TimeoutError) as e:
            if face == "async":
                asyncio.run(in_async_with())
            else:
                with motionlink.PowerCube(port) as cube:
                    cube.home()
                    cut_under_the_move()
                    cube.move_to(2.0, velocity=0.2)
    assert e.value.stop_unconfirmed and "may still be moving" in str(e.value)
    notes = getattr(e.value, "__notes__", [])
    assert len(notes) == 1 and notes[0].startswith("then the end of the session: "), notes
