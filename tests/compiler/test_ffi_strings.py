"""STRING across the FFI: FUNCTION arguments and results and FB inputs as Python str (bytes as
latin-1), checked against the 126-byte body MatIEC gives every STRING."""

from __future__ import annotations

import pytest

from armbench.compiler import compile_files
from armbench.compiler.ffi import PlcArgumentError

SOURCE = """
FUNCTION Greet : STRING
  VAR_INPUT who : STRING; n : INT; END_VAR
  Greet := CONCAT('Hi ', who, INT_TO_STRING(n));
END_FUNCTION
FUNCTION_BLOCK Logger
  VAR_INPUT line : STRING; END_VAR
  VAR_OUTPUT last : STRING; count : INT; END_VAR
  last := line; count := count + LEN(line);
END_FUNCTION_BLOCK
"""


@pytest.fixture(scope="module")
def module(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    path = tmp_path_factory.mktemp("ffi_strings") / "pous.st"
    path.write_text(SOURCE, encoding="utf-8")
    return compile_files([path])


def test_function_with_strings(module) -> None:  # type: ignore[no-untyped-def]
    assert module.call("Greet", who="Bob", n=7) == "Hi Bob7"
    assert module.call("Greet", who="caf\xe9", n=-1) == "Hi caf\xe9-1"  # one byte, 0xE9


def test_fb_string_inputs_and_outputs(module) -> None:  # type: ignore[no-untyped-def]
    fb = module.new_fb("Logger")
    fb(line="abc")
    fb(line="x" * 126)
    assert fb.get("last") == "x" * 126
    assert fb.get("count") == 129
    with pytest.raises(PlcArgumentError, match="at most 126"):
        fb(line="x" * 127)
    with pytest.raises(PlcArgumentError, match="expected a str"):
        fb(line=5)
    with pytest.raises(PlcArgumentError, match="latin-1"):
        fb(line="\u20ac")
