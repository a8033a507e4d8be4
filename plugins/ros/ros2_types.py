"""ROS 2 message types for Cyclone DDS, made from ``rosbags``' ROS 2 (Jazzy) definitions, so that
the layouts have one source: the one the bag export writes with.

ROS 2 (rmw_cyclonedds) names a message ``pkg/msg/Name`` on the wire ``pkg::msg::dds_::Name_``
and encodes it as plain CDR; a service is a request and a reply topic whose samples begin with
rmw_cyclonedds' request header (the client's 64-bit id and a 64-bit sequence number, which the
reply repeats). ``uint8[]`` fields are carried as Python ``bytes``.
"""

from __future__ import annotations

import dataclasses
import types as pytypes
from functools import cache
from typing import Any

from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t

#: ROS 2 service definitions that rosbags' message store lacks
SERVICES = {"std_srvs/srv/Trigger": ("", "bool success\nstring message\n")}

_BASE: dict[str, Any] = {
    "bool": bool, "byte": t.uint8, "char": t.uint8, "int8": t.int8, "uint8": t.uint8, "int16": t.int16,
    "uint16": t.uint16, "int32": t.int32, "uint32": t.uint32, "int64": t.int64, "uint64": t.uint64,
    "float32": t.float32, "float64": t.float64, "string": str,
}  # fmt: skip


@cache
def store() -> Any:
    """rosbags' ROS 2 Jazzy type store, with :data:`SERVICES`' request and response types."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    s = get_typestore(Stores.ROS2_JAZZY)
    for name, (request, response) in SERVICES.items():
        for part, text in (("Request", request), ("Response", response)):
            # the parser files a srv's parts under pkg/srv/msg/...: keyed here by their ROS 2 names
            (definition,) = get_types_from_msg(text, f"{name}_{part}").values()
            s.register({f"{name}_{part}": definition})
    return s


def dds_name(ros_name: str) -> str:
    """``sensor_msgs/msg/Image`` -> ``sensor_msgs::msg::dds_::Image_``."""
    package, kind, name = ros_name.split("/")
    return f"{package}::{kind}::dds_::{name}_"


@cache
def message(ros_name: str, request_header: bool = False) -> type:
    """The IdlStruct of a ROS 2 message (``pkg/msg/Name``); ``request_header``: preceded by
    rmw_cyclonedds' service header (``client_id``, ``sequence``)."""
    s = store()
    _, fields = s.fielddefs[ros_name]
    annotations: dict[str, Any] = {}
    if request_header:
        annotations.update(client_id=t.uint64, sequence=t.int64)
    for name, node in fields:
        annotations[name] = _field_type(node)
    if not fields:  # an empty ROS 2 message holds one byte (rosidl's placeholder member)
        annotations["structure_needs_at_least_one_member"] = t.uint8
    cls_name = ros_name.replace("/", "_") + ("_with_header" if request_header else "")

    def body(ns: dict[str, Any]) -> None:
        ns["__annotations__"] = annotations
        ns["__module__"] = __name__

    cls = dataclasses.dataclass(pytypes.new_class(cls_name, (IdlStruct,), {"typename": dds_name(ros_name)}, body))
    raw = [name for name, node in fields if _is_byte_sequence(node)]
    if raw:
        _bytes_on_the_wire(cls, raw)
    return cls


def _is_byte_sequence(node: tuple[Any, Any]) -> bool:
    from rosbags.interfaces import Nodetype

    kind, detail = node
    return kind == Nodetype.SEQUENCE and detail == ((Nodetype.BASE, ("uint8", 0)), 0)


def _bytes_on_the_wire(cls: type, names: list[str]) -> None:
    """Carry these ``sequence<uint8>`` members as Python ``bytes``. Cyclone's type description
    (what discovery compares) stays ``sequence<uint8>``, as ROS 2 declares them; only the Python
    side of the encoding changes, to its bytes machine, which puts the same bytes on the wire (a
    4-aligned uint32 length, then the bytes) without a Python int per pixel."""
    from cyclonedds.idl._machinery import BytesMachine

    idl = cls.__idl__  # type: ignore[attr-defined]
    idl.populate()
    for machine in (idl.v1_machine, idl.v2_machine):
        for name in names:
            machine.members_machines[name] = BytesMachine()


def _field_type(node: tuple[Any, Any]) -> Any:
    from rosbags.interfaces import Nodetype

    kind, detail = node
    if kind == Nodetype.BASE:
        name, bound = detail
        return t.bounded_str[bound] if name == "string" and bound else _BASE[name]
    if kind == Nodetype.NAME:
        return message(detail)
    element, size = detail
    if kind == Nodetype.ARRAY:
        return t.array[_field_type(element), size]
    return t.sequence[_field_type(element), size] if size else t.sequence[_field_type(element)]
