"""hil.device as a dispatcher: the `Device` class stays under 200 lines, every message type the
device handles has exactly one entry in hil.handlers.HANDLERS (and every command one in
COMMANDS), `Device.receive` reaches a handler only through that table, and a `Device` has every
member its parts may use (hil.device_state.DeviceView)."""
from __future__ import annotations

import ast
import inspect
from collections import Counter
from pathlib import Path

import pytest

pytest.importorskip("pymavlink")

from hil import handlers  # noqa: E402
from hil import mavlink_stewart as ms  # noqa: E402
from hil.device import Device  # noqa: E402
from hil.device_state import DeviceView  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"

# What a host may send the device (hil.device's module doc), and the commands it carries out.
HANDLED = {"LEG_SETPOINT", "POSE_SETPOINT", "COMMAND_LONG", "COMMAND_INT", "PARAM_REQUEST_LIST",
           "PARAM_REQUEST_READ", "PARAM_SET", "LOCKSTEP"}
COMMANDS = {"MAV_CMD_COMPONENT_ARM_DISARM", "MAV_CMD_NAV_RETURN_TO_LAUNCH",
            "MAV_CMD_GET_HOME_POSITION", "MAV_CMD_REQUEST_MESSAGE"}
CLASS_LINES = 200


@pytest.fixture(scope="module")
def model():
    return load_scene(SCENE)


def _table_keys(name: str) -> list[str]:
    """The keys of the dict literal assigned to `name` in hil/handlers.py, as written (a
    repeated key would be silently overwritten at run time, so the source is read)."""
    tree = ast.parse((ROOT / "hil" / "handlers.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.AnnAssign) and getattr(node.target, "id", None) == name:
            assert isinstance(node.value, ast.Dict)
            return [ast.unparse(k) for k in node.value.keys]
    raise AssertionError(f"hil/handlers.py assigns no {name}")


def test_the_device_class_is_under_200_lines():
    lines, _ = inspect.getsourcelines(Device)
    assert len(lines) < CLASS_LINES, len(lines)


def test_every_handled_message_type_has_exactly_one_entry():
    keys = _table_keys("HANDLERS")
    assert [k for k, n in Counter(keys).items() if n > 1] == []
    assert sorted(keys) == sorted(f"ms.MAVLINK_MSG_ID_{m}" for m in HANDLED)
    assert set(handlers.HANDLERS) == {getattr(ms, f"MAVLINK_MSG_ID_{m}") for m in HANDLED}
    assert len(handlers.HANDLERS) == len(HANDLED)


def test_every_command_has_exactly_one_entry():
    keys = _table_keys("COMMANDS")
    assert [k for k, n in Counter(keys).items() if n > 1] == []
    assert sorted(keys) == sorted(f"ms.{c}" for c in COMMANDS)
    assert set(handlers.COMMANDS) == {getattr(ms, c) for c in COMMANDS}


def test_every_handler_is_in_a_table_and_none_is_a_method():
    """A message handler lives in hil.handlers and is reached through a table, never as a
    method of Device."""
    tabled = set(handlers.HANDLERS.values()) | set(handlers.COMMANDS.values())
    on = {f for n, f in vars(handlers).items() if n.startswith("on_") and inspect.isfunction(f)}
    assert on and on <= tabled
    assert [n for n in vars(Device) if n.startswith(("_on_", "on_"))] == []


def _message(msg_id: int):
    """A message of the type `msg_id` with every field zero."""
    cls = ms.mavlink_map[msg_id]
    types = dict(zip(cls.fieldnames, cls.fieldtypes))
    sizes = dict(zip(cls.ordered_fieldnames, cls.array_lengths))
    return cls(*(b"" if types[f] == "char" else [0] * sizes[f] if sizes[f] else 0
                 for f in cls.fieldnames))


def test_receive_dispatches_through_the_table(model, monkeypatch):
    """Each handled type reaches its table entry once; any other type is answered by nothing."""
    dev = Device(model)
    calls: list[int] = []
    for msg_id in list(handlers.HANDLERS):
        monkeypatch.setitem(handlers.HANDLERS, msg_id,
                            lambda d, m, i=msg_id: calls.append(i) or [])
    for msg_id in sorted(handlers.HANDLERS):
        assert dev.receive(_message(msg_id)) == []
    assert calls == sorted(handlers.HANDLERS)
    other = ms.MAVLINK_MSG_ID_HEARTBEAT
    assert other not in handlers.HANDLERS
    assert dev.receive(_message(other)) == [] and len(calls) == len(handlers.HANDLERS)


def test_a_device_has_every_member_its_parts_use(model):
    dev = Device(model)
    members = set(DeviceView.__annotations__) | {
        n for n, v in vars(DeviceView).items()
        if not n.startswith("_") and (inspect.isfunction(v) or isinstance(v, property))}
    assert len(members) > 30
    assert sorted(m for m in members if not hasattr(dev, m)) == []
