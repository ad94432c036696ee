"""Byte offsets of a few fields inside MuJoCo's ``mjData`` struct (``time``, ``ncon``, ``nefc``,
the ``efc_force`` pointer), for the compiled per-step call of :mod:`rblog.adapters.mujoco`
(``rblog.adapters._hook.StepRecord``), which reads them straight from ``d``.

The offsets come from the bindings' own description of the struct (``mujoco.introspect``: every
field in declaration order with its C type), laid out by the C rules of x86-64 and aarch64
(each member at a multiple of its alignment, a struct padded to its largest alignment), and are
used only after :func:`verified` read back, at those offsets in the caller's ``d``, what the
bindings report: ``time``, ``ncon``, ``nefc`` and the addresses of ``qpos``, ``qvel`` and (when there are
contacts, constraints) ``contact``, ``efc_force``. Anything else: None, and the
recorder stays on its Python path."""

from __future__ import annotations

import ctypes

#: size and alignment of the scalar C types mjData's fields use
_SCALARS = {"int": 4, "mjtNum": 8, "mjtSize": 8, "size_t": 8, "uintptr_t": 8, "uint64_t": 8,
            "mjtBool": 1, "float": 4, "double": 8, "char": 1, "unsigned char": 1}


def _size_align(t, structs):
    """(size, alignment) in bytes of an introspect type node."""
    name = type(t).__name__
    if name == "PointerType":
        return 8, 8
    if name == "ArrayType":
        size, align = _size_align(t.inner_type, structs)
        count = 1
        for e in t.extents:
            count *= int(e)
        return size * count, align
    if name == "ValueType":
        if t.name in _SCALARS:
            return _SCALARS[t.name], _SCALARS[t.name]
        if t.name in structs:
            return _struct_layout(structs[t.name], structs)[1:]
    raise ValueError(f"mjData layout: type {t!r} not known")


def _struct_layout(decl, structs):
    """({field: offset}, size, alignment) of a struct declaration."""
    offsets, pos, align_max = {}, 0, 1
    for f in decl.fields:
        size, align = _size_align(f.type, structs)
        pos = (pos + align - 1) // align * align
        offsets[f.name] = pos
        pos += size
        align_max = max(align_max, align)
    return offsets, (pos + align_max - 1) // align_max * align_max, align_max


_OFFSETS = []  # offsets(), once a process: the loaded mujoco's layout does not change


def offsets():
    """{field: byte offset in mjData} from mujoco.introspect, or None when it is not there or
    holds a type this does not know."""
    if not _OFFSETS:
        try:
            from mujoco.introspect import structs

            table = structs.STRUCTS
            _OFFSETS.append(_struct_layout(table["mjData"], table)[0])
        except (ImportError, KeyError, AttributeError, ValueError, TypeError):
            _OFFSETS.append(None)
    return _OFFSETS[0]


def _addr(a) -> int:
    return int(a.__array_interface__["data"][0])


def verified(d):
    """(time, ncon, nefc, efc_force pointer) byte offsets in ``d`` (a mujoco.MjData), each
    checked against the bindings' own values in ``d``; None when any check fails."""
    off = offsets()
    need = ("time", "ncon", "nefc", "efc_force", "qpos", "qvel", "contact")
    if off is None or any(f not in off for f in need):
        return None
    base = int(d._address)
    dbl = lambda f: ctypes.c_double.from_address(base + off[f]).value  # noqa: E731
    i32 = lambda f: ctypes.c_int.from_address(base + off[f]).value  # noqa: E731
    ptr = lambda f: ctypes.c_uint64.from_address(base + off[f]).value  # noqa: E731
    try:
        ok = (dbl("time") == float(d.time) and i32("ncon") == int(d.ncon)
              and i32("nefc") == int(d.nefc) and ptr("qpos") == _addr(d.qpos)
              and ptr("qvel") == _addr(d.qvel)
              and (int(d.ncon) == 0 or ptr("contact") == _addr(d.contact.dist))
              and (int(d.nefc) == 0 or ptr("efc_force") == _addr(d.efc_force)))
    except (AttributeError, ValueError, TypeError):
        return None
    return (off["time"], off["ncon"], off["nefc"], off["efc_force"]) if ok else None


def efc_force_matches(d, offset: int) -> bool:
    """Whether the pointer at ``offset`` in ``d`` is the address of ``d.efc_force`` (checked
    once there are constraints)."""
    if int(d.nefc) == 0:
        return True
    return ctypes.c_uint64.from_address(int(d._address) + offset).value == _addr(d.efc_force)
