"""A FUNCTION_BLOCK's ARRAY input takes a numpy array as well as a list, although the module
loading the program no longer imports numpy itself."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from armbench.compiler import compile_files

SUM = """FUNCTION_BLOCK Sum3
  VAR_INPUT
    V : ARRAY[0..2, 0..1] OF REAL;
  END_VAR
  VAR_OUTPUT
    Total : REAL;
  END_VAR
  VAR
    i : INT;
    j : INT;
  END_VAR
  Total := 0.0;
  FOR i := 0 TO 2 DO
    FOR j := 0 TO 1 DO
      Total := Total + V[i, j] * INT_TO_REAL(i * 2 + j + 1);
    END_FOR;
  END_FOR;
END_FUNCTION_BLOCK
"""


def test_an_array_input_takes_a_numpy_array_and_a_list(tmp_path: Path) -> None:
    src = tmp_path / "sum3.st"
    src.write_text(SUM)
    fb = compile_files([src]).new_fb("Sum3")
    values = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]], dtype=np.float32)
    expected = sum(v * (k + 1) for k, v in enumerate(values.ravel().tolist()))  # 91
    fb.set(V=values)
    fb()
    assert fb.Total == expected
    fb.set(V=[[0.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
    fb()
    assert fb.Total == 6.0
