"""The ctypes twins in `lavatube.wire` against `layouts.json`, which a Rust test
(`common/tests/python_layouts.rs`) pins to the compiler's layout of the Rust types."""

import ctypes
import json
from pathlib import Path

import numpy as np
import pytest

from lavatube import wire

LAYOUTS = json.loads(
    (Path(__file__).resolve().parents[1] / "lavatube" / "layouts.json").read_text())


def test_every_rust_type_has_a_twin():
    assert sorted(t.__name__ for t in wire.ALL) == sorted(LAYOUTS["types"])


@pytest.mark.parametrize("ctype", wire.ALL, ids=lambda t: t.__name__)
def test_ctypes_layout_matches_rust(ctype):
    rust = LAYOUTS["types"][ctype.__name__]
    assert ctype.type_name() == rust["type_name"]
    assert (ctypes.sizeof(ctype), ctypes.alignment(ctype)) == (rust["size"], rust["align"])
    assert [[name, getattr(ctype, name).offset] for name, _ in ctype._fields_] == rust["fields"]
    # The numpy view the readers build agrees too.
    assert np.dtype(ctype).itemsize == rust["size"]


def test_constants_match_rust():
    assert {name: getattr(wire, name) for name in LAYOUTS["constants"]} == LAYOUTS["constants"]
