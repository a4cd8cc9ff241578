"""Find sensor fields inside decoded messages by their shape, at any nesting depth.

Works on ROS 2 messages decoded by mcap-ros2-support (objects with ``__slots__``), on rosbags' messages
(dataclasses) and on JSON objects (dicts) alike. Recognised: ``sensor_msgs/Imu`` (orientation, angular_velocity,
linear_acceleration), ``geometry_msgs/Wrench`` (force, torque), ``Vector3`` and ``Quaternion``, including inside
custom messages and fixed-length arrays of them.
"""

from __future__ import annotations

import dataclasses
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

Path = tuple[str | int, ...]

_SKIP = ("header", "stamp", "covariance")
UNITS = {
    "orientation": "1",
    "angular_velocity": "rad/s",
    "linear_acceleration": "m/s²",
    "force": "N",
    "torque": "N·m",
}


@dataclass(frozen=True)
class FieldSpec:
    """A numeric leaf: where it is, what to call it, and whose header stamps it."""

    path: Path
    name: str
    unit: str
    header: Path | None  # path of the nearest enclosing object with a header, if any


def keys(obj: object) -> tuple[str, ...]:
    if isinstance(obj, dict):
        return tuple(obj)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):  # rosbags' messages
        return tuple(f.name for f in dataclasses.fields(obj) if not f.name.startswith("__"))  # not __msgtype__
    slots = getattr(type(obj), "__slots__", None)
    return tuple(slots) if slots else ()


def child(obj: object, key: str | int) -> object:
    if isinstance(key, int):
        return obj[key]  # type: ignore[index]
    if isinstance(obj, dict):
        return obj[key]
    return getattr(obj, key)


def get(obj: object, path: Path) -> object:
    for key in path:
        obj = child(obj, key)
    return obj


def parse_path(text: str) -> Path:
    """``"feet[0].force.z"`` -> ``("feet", 0, "force", "z")``."""
    out: list[str | int] = []
    for part in text.split("."):
        while "[" in part:
            head, _, rest = part.partition("[")
            index, _, part = rest.partition("]")
            if head:
                out.append(head)
            out.append(int(index))
        if part:
            out.append(part)
    return tuple(out)


def format_path(path: Path) -> str:
    text = ""
    for key in path:
        text += f"[{key}]" if isinstance(key, int) else (f".{key}" if text else key)
    return text


def _is_num(value: object) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _has_nums(obj: object, names: Sequence[str]) -> bool:
    ks = keys(obj)
    return all(n in ks and _is_num(child(obj, n)) for n in names)


def _is_vector(obj: object) -> bool:
    return _has_nums(obj, "xyz")


def stamp_seconds(obj: object, header: Path) -> float | None:
    """Seconds of the header stamp at ``header`` (ROS 2 ``sec``/``nanosec``, ROS 1 style ``secs``/``nsecs``).

    None when absent or zero, so that the log time is used instead.
    """
    try:
        stamp = get(obj, (*header, "header", "stamp"))
        ks = keys(stamp)
        sec = child(stamp, "sec" if "sec" in ks else "secs")
        nsec = child(stamp, "nanosec" if "nanosec" in ks else "nsecs")
        value = float(sec) + float(nsec) * 1e-9
    except (AttributeError, KeyError, IndexError, TypeError, ValueError):
        return None
    return value if value > 0 else None


def infer_fields(msg: object) -> list[FieldSpec]:
    """All recognised sensor fields of one decoded message, in a stable order."""
    found: list[FieldSpec] = []

    def walk(obj: object, path: Path, header: Path | None, depth: int) -> None:
        if depth > 8:
            return
        ks = keys(obj)
        if "header" in ks:
            header = path
        if _is_vector(obj):
            axes = "xyzw" if _has_nums(obj, "xyzw") else "xyz"
            parent = next((k for k in reversed(path) if isinstance(k, str)), "")
            unit = UNITS.get(parent, "")
            found.extend(FieldSpec((*path, a), format_path((*path, a)), unit, header) for a in axes)
            return
        for key in ks:
            if any(s in key for s in _SKIP):
                continue
            value = child(obj, key)
            if isinstance(value, list | tuple):
                if 0 < len(value) <= 16 and keys(value[0]):
                    for i in range(len(value)):
                        walk(value[i], (*path, key, i), header, depth + 1)
            elif keys(value):
                walk(value, (*path, key), header, depth + 1)

    walk(msg, (), None, 0)
    # A *Stamped message is a header around one field: name channels without that wrapper ("force.x", not
    # "wrench.force.x"), so the same sensor reads the same whether stamped or not.
    ks = [k for k in keys(msg) if k != "header"]
    if "header" in keys(msg) and len(ks) == 1:
        wrapper = ks[0]
        found = [
            FieldSpec(
                f.path,
                format_path(f.path[1:]) if f.path[0] == wrapper and len(f.path) > 1 else f.name,
                f.unit,
                f.header,
            )
            for f in found
        ]
    return found
