"""rblog's protobuf schemas (file ``rblog/log.proto``, package ``rblog``), built at run time.

The schemas are declared here as Python tables and turned into a ``FileDescriptorProto``, so no
``protoc`` is needed at install time and the code works with any protobuf >= 5. docs/log-format.md
prints the same schema as ``.proto`` text; field numbers are part of the log contract.

The hot per-sample messages (``State``, ``Metrics``) are not built with the protobuf runtime: they
are encoded straight from numpy buffers by :func:`encode_rows`, which lays out ordinary protobuf
wire format (fixed-width scalars and packed repeated fields in field-number order). Decoding always
goes through the protobuf runtime and the schema embedded in the log.
"""

from __future__ import annotations

from functools import cache

import numpy as np
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

PACKAGE = "rblog"
FILE_NAME = "rblog/log.proto"

_F = descriptor_pb2.FieldDescriptorProto
_TYPES = {
    "double": _F.TYPE_DOUBLE,
    "int64": _F.TYPE_INT64,
    "uint32": _F.TYPE_UINT32,
    "sfixed64": _F.TYPE_SFIXED64,
    "sfixed32": _F.TYPE_SFIXED32,
    "bool": _F.TYPE_BOOL,
    "string": _F.TYPE_STRING,
}

# message -> [(number, name, type, label)], label: "" (singular), "repeated", "optional"
MESSAGES: dict[str, list[tuple[int, str, str, str]]] = {
    "Run": [
        (1, "rblog_log_format", "uint32", ""),
        (2, "integrator", "string", ""),
        (3, "orthonormalize", "string", ""),
        (4, "dt", "double", ""),
        (5, "log_every", "int64", ""),
        (6, "duration_s", "double", ""),
        (7, "rblog_version", "string", ""),
        (8, "scene_path", "string", ""),
        (9, "scene_toml", "string", ""),
        (10, "scene_resolved_json", "string", ""),
        (11, "seed", "int64", "optional"),
        (12, "writer", "string", ""),
        (13, "combine_friction", "string", ""),
        (14, "combine_restitution", "string", ""),
        (15, "engine_settings_json", "string", ""),
        (20, "body_name", "string", "repeated"),
        (21, "body_shape", "int64", "repeated"),
        (22, "body_size", "double", "repeated"),
        (23, "body_mass", "double", "repeated"),
        (24, "body_inertia_diag", "double", "repeated"),
        (25, "body_force_world", "double", "repeated"),
        (26, "body_torque_world", "double", "repeated"),
        (27, "body_restitution", "double", "repeated"),
        (28, "body_friction", "double", "repeated"),
        (29, "body_group", "int64", "repeated"),
        (30, "gravity", "double", "repeated"),
        (31, "ground", "bool", ""),
        (32, "ground_normal", "double", "repeated"),
        (33, "ground_offset", "double", ""),
        (34, "ground_restitution", "double", ""),
        (35, "ground_friction", "double", ""),
        (36, "static_box_position", "double", "repeated"),
        (37, "static_box_quat_wxyz", "double", "repeated"),
        (38, "static_box_half_extents", "double", "repeated"),
        (39, "static_box_restitution", "double", "repeated"),
        (40, "static_box_friction", "double", "repeated"),
        (41, "body_kind", "int64", "repeated"),
        (42, "body_parent", "int64", "repeated"),
        (43, "body_impulse_supplied", "int64", "repeated"),
        (44, "body_work_supplied", "int64", "repeated"),
        (45, "joint_name", "string", "repeated"),
        (46, "joint_type", "int64", "repeated"),
        (47, "joint_body", "int64", "repeated"),
        (48, "joint_anchor_body", "double", "repeated"),
        (49, "joint_anchor_parent", "double", "repeated"),
        (50, "joint_axis_body", "double", "repeated"),
        (51, "joint_axis_parent", "double", "repeated"),
        (52, "joint_range", "double", "repeated"),
        (53, "geom_name", "string", "repeated"),
        (54, "geom_body", "int64", "repeated"),
        (55, "geom_type", "int64", "repeated"),
        (56, "geom_pos_body", "double", "repeated"),
        (57, "geom_quat_wxyz_body", "double", "repeated"),
        (58, "geom_size", "double", "repeated"),
        (59, "geom_vert_adr", "int64", "repeated"),
        (60, "geom_vert_num", "int64", "repeated"),
        (61, "geom_friction", "double", "repeated"),
        (62, "geom_restitution", "double", "repeated"),
        (63, "geom_collide_group", "int64", "repeated"),
        (64, "geom_collide_mask", "int64", "repeated"),
        (65, "mesh_vert", "double", "repeated"),
        (66, "collide_rule", "string", ""),
        (67, "joint_quat_parent", "double", "repeated"),
        (68, "collide_parent", "bool", ""),
        (69, "joint_armature", "double", "repeated"),
    ],
    "State": [
        (1, "step", "sfixed64", ""),
        (2, "t", "double", ""),
        (3, "position", "double", "repeated"),
        (4, "quat_wxyz", "double", "repeated"),
        (5, "rotation", "double", "repeated"),
        (6, "velocity", "double", "repeated"),
        (7, "linear_momentum", "double", "repeated"),
        (8, "angular_velocity", "double", "repeated"),
        (9, "angular_momentum", "double", "repeated"),
        (10, "energy_translational", "double", "repeated"),
        (11, "energy_rotational", "double", "repeated"),
        (12, "energy_potential", "double", "repeated"),
        (13, "ortho_error", "double", "repeated"),
        (14, "quat_norm_error", "double", "repeated"),
        (15, "total_linear_momentum", "double", "repeated"),
        (16, "total_angular_momentum", "double", "repeated"),
        (17, "total_energy", "double", ""),
        # v3: the per-interval channels (INTERVAL_CHANNELS; the kinds added last, integration
        # and joint work, after the others), present when supplied
        (18, "impulse_contact_linear", "double", "repeated"),
        (19, "impulse_contact_angular", "double", "repeated"),
        (20, "impulse_applied_linear", "double", "repeated"),
        (21, "impulse_applied_angular", "double", "repeated"),
        (22, "impulse_passive_linear", "double", "repeated"),
        (23, "impulse_passive_angular", "double", "repeated"),
        (24, "impulse_actuator_linear", "double", "repeated"),
        (25, "impulse_actuator_angular", "double", "repeated"),
        (26, "impulse_joint_linear", "double", "repeated"),
        (27, "impulse_joint_angular", "double", "repeated"),
        (28, "work_applied", "double", "repeated"),
        (29, "work_passive", "double", "repeated"),
        (30, "work_actuator", "double", "repeated"),
        (31, "impulse_integration_linear", "double", "repeated"),
        (32, "impulse_integration_angular", "double", "repeated"),
        (33, "work_joint", "double", "repeated"),
    ],
    "Contacts": [
        (1, "step", "sfixed64", ""),
        (2, "t", "double", ""),
        (3, "body_a", "sfixed32", "repeated"),
        (4, "body_b", "sfixed32", "repeated"),
        (5, "point", "double", "repeated"),
        (6, "normal", "double", "repeated"),
        (7, "separation", "double", "repeated"),
        (8, "normal_impulse", "double", "repeated"),
        (9, "friction_impulse", "double", "repeated"),
        (10, "kind", "sfixed32", "repeated"),
    ],
    "Metrics": [
        (1, "step", "sfixed64", ""),
        (2, "t", "double", ""),
        (3, "total_energy", "double", ""),
        (4, "energy_translational", "double", ""),
        (5, "energy_rotational", "double", ""),
        (6, "energy_potential", "double", ""),
        (7, "total_linear_momentum", "double", "repeated"),
        (8, "total_angular_momentum", "double", "repeated"),
        (9, "ortho_error_max", "double", ""),
        (10, "quat_norm_error_max", "double", ""),
    ],
    "Status": [
        (1, "complete", "bool", ""),
        (2, "truncated", "bool", ""),
        (3, "reason", "string", ""),
    ],
}


@cache
def file_descriptor() -> descriptor_pb2.FileDescriptorProto:
    """The ``rblog/log.proto`` file as a descriptor (proto3)."""
    fd = descriptor_pb2.FileDescriptorProto(name=FILE_NAME, package=PACKAGE, syntax="proto3")
    for msg_name, fields in MESSAGES.items():
        msg = fd.message_type.add(name=msg_name)
        for number, name, typ, label in fields:
            f = msg.field.add(name=name, number=number, type=_TYPES[typ], json_name=_json_name(name))
            f.label = _F.LABEL_REPEATED if label == "repeated" else _F.LABEL_OPTIONAL
            if label == "optional":  # proto3 `optional`: a synthetic oneof named `_<field>`
                f.proto3_optional = True
                f.oneof_index = len(msg.oneof_decl)
                msg.oneof_decl.add(name=f"_{name}")
    return fd


def _json_name(name: str) -> str:
    head, *rest = name.split("_")
    return head + "".join(w[:1].upper() + w[1:] for w in rest)


@cache
def file_descriptor_set_bytes() -> bytes:
    """The serialized ``FileDescriptorSet`` embedded as every rblog MCAP schema's data."""
    fds = descriptor_pb2.FileDescriptorSet()
    fds.file.append(file_descriptor())
    return fds.SerializeToString()


@cache
def message_class(name: str):
    """The protobuf class of ``rblog.<name>`` (from a private descriptor pool)."""
    pool = descriptor_pool.DescriptorPool()
    pool.Add(file_descriptor())
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(f"{PACKAGE}.{name}"))


def field_numbers(name: str) -> dict[str, int]:
    return {fname: num for num, fname, _, _ in MESSAGES[name]}


# --- wire format helpers ------------------------------------------------------------------------
# Wire types: 0 varint, 1 fixed 64-bit, 2 length-delimited, 5 fixed 32-bit.

def varint(value: int) -> bytes:
    """Protobuf base-128 varint of a non-negative int."""
    out = bytearray()
    while True:
        b = value & 0x7F
        value >>= 7
        if value:
            out.append(b | 0x80)
        else:
            out.append(b)
            return bytes(out)


def tag(number: int, wire_type: int) -> bytes:
    return varint((number << 3) | wire_type)


def len_field(number: int, payload: bytes) -> bytes:
    """A length-delimited field (packed array, string, or sub-message)."""
    return tag(number, 2) + varint(len(payload)) + payload


def fixed64_field(number: int, value_le8: bytes) -> bytes:
    return tag(number, 1) + value_le8


_U8 = np.uint8


def encode_rows(rows: int, parts: list) -> np.ndarray:
    """Encode ``rows`` messages of identical layout at once; returns a (rows, L) uint8 array.

    ``parts`` lists, in order, ``("double", number, values)`` with values of shape (rows,) (a
    singular double), ``("sfixed64", number, values)``, ``("packed_double", number, values)`` with
    shape (rows, k) (a packed repeated double of k elements per row; k may be 0).
    """
    cols = []
    for kind, number, values in parts:
        if kind == "double":
            cols.append(_const(rows, tag(number, 1)))
            cols.append(_bytes_of(np.asarray(values, "<f8").reshape(rows, 1)))
        elif kind == "sfixed64":
            cols.append(_const(rows, tag(number, 1)))
            cols.append(_bytes_of(np.asarray(values, "<i8").reshape(rows, 1)))
        elif kind == "packed_double":
            v = np.asarray(values, "<f8").reshape(rows, -1)
            cols.append(_const(rows, tag(number, 2) + varint(8 * v.shape[1])))
            if v.shape[1]:
                cols.append(_bytes_of(v))
        else:  # pragma: no cover - programming error
            raise ValueError(kind)
    return np.concatenate(cols, axis=1)


def _const(rows: int, b: bytes) -> np.ndarray:
    return np.broadcast_to(np.frombuffer(b, _U8), (rows, len(b)))


def _bytes_of(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    return a.view(_U8).reshape(a.shape[0], -1)


def packed_doubles(number: int, values: np.ndarray) -> bytes:
    return len_field(number, np.ascontiguousarray(values, "<f8").tobytes())


def packed_sfixed32(number: int, values: np.ndarray) -> bytes:
    return len_field(number, np.ascontiguousarray(values, "<i4").tobytes())


def double_field(number: int, value: float) -> bytes:
    return fixed64_field(number, np.float64(value).astype("<f8").tobytes())


def sfixed64_field(number: int, value: int) -> bytes:
    return fixed64_field(number, np.int64(value).astype("<i8").tobytes())
