"""Comparing two stores as a reader sees them, and checking the one NaN a store holds.

Two stores of the same scan are the same when every dataset has the same
dtype, shape and values (NaN equal to NaN), the same attributes and the same
dimension scales, and the groups the same attributes, less the times of
writing and the executor that computed the rows. Bits are not compared
directly: a NaN's sign and payload depend on the CPU's vector unit. Instead
each store must hold only the canonical NaN (:func:`smarticle_mjx.store.canonical`),
so that a writer letting another NaN through fails here on any machine.
"""

from __future__ import annotations

import json

import h5py
import numpy as np

# attributes that say when or by what a store was written, not what it holds
WHEN = ("created", "finished")
CANONICAL_NAN = {np.dtype(np.float32): 0x7FC00000, np.dtype(np.float64): 0x7FF8000000000000}


def _attrs(obj) -> dict:
    out = {}
    for k, v in obj.attrs.items():
        if k in ("DIMENSION_LIST", "REFERENCE_LIST"):  # object references: compared as scale names below
            continue
        out[k] = v.tolist() if isinstance(v, np.ndarray) else (v.decode() if isinstance(v, bytes) else v)
    return out


def read_store(path) -> dict:
    """{name: (kind, attrs, value, scales)} of every group and dataset, root included."""
    out = {}
    with h5py.File(path, "r") as f:
        out["/"] = ("group", _attrs(f), None, None)

        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                scales = [[s.name for s in dim.values()] for dim in obj.dims]
                out[name] = ("dataset", _attrs(obj), obj[()], scales)
            else:
                out[name] = ("group", _attrs(obj), None, None)
        f.visititems(visit)
    return out


def non_canonical_nans(path) -> list[str]:
    """Float datasets of the store holding a NaN other than the canonical one."""
    bad = []
    for name, (kind, _, value, _) in read_store(path).items():
        if kind != "dataset" or value.dtype not in CANONICAL_NAN:
            continue
        nan = np.isnan(value)
        if nan.any():
            bits = value[nan].view(np.uint32 if value.dtype == np.float32 else np.uint64)
            if (bits != CANONICAL_NAN[value.dtype]).any():
                bad.append(f"{name}: {sorted({hex(int(b)) for b in bits})}")
    return bad


def assert_same_store(a, b, ignore_config=("executor",)) -> None:
    """``a`` and ``b`` read the same (see the module's text) and hold only canonical NaNs."""
    ra, rb = read_store(a), read_store(b)
    assert sorted(ra) == sorted(rb), sorted(set(ra) ^ set(rb))
    for name in ra:
        kind, attrs_a, va, scales_a = ra[name]
        _, attrs_b, vb, scales_b = rb[name]
        for k in WHEN:
            attrs_a.pop(k, None)
            attrs_b.pop(k, None)
        if "config" in attrs_a and name == "/":
            ca, cb = json.loads(attrs_a.pop("config")), json.loads(attrs_b.pop("config"))
            for k in ignore_config:
                ca.pop(k, None)
                cb.pop(k, None)
            assert ca == cb, "stored configurations differ"
        assert attrs_a == attrs_b, f"attributes of {name} differ"
        if kind == "dataset":
            assert va.dtype == vb.dtype and va.shape == vb.shape, f"{name}: {va.dtype}{va.shape} vs {vb.dtype}{vb.shape}"
            assert scales_a == scales_b, f"dimension scales of {name} differ"
            if va.dtype == object:  # labels (strings): values, not pointers
                assert va.tolist() == vb.tolist(), f"dataset {name} differs"
            else:
                np.testing.assert_array_equal(va, vb, err_msg=f"dataset {name} differs")  # NaN equals NaN
    for path in (a, b):
        bad = non_canonical_nans(path)
        assert not bad, f"{path} holds non-canonical NaNs: {bad}"
