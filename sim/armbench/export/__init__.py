"""Exports for real PLCs: the OpenPLC Runtime upload file and PLCopen TC6 XML.

``armbench export`` checks the sources (default ``st/*.st`` + ``plc_project/Controller.st``),
orders them types first, and writes into the ``--out`` folder (``armbench export
--regenerate``: the checkout's own ``plc_project/``, from the checkout's sources):

- ``openplc/arm_controller.st``: one ST file (program + configuration + the library
  declarations it uses), the sources' text behind a generated header (:mod:`.openplc`);
- ``plcopen/arm_controller.xml``: PLCopen TC6 XML v2.01 for CODESYS and the OpenPLC Editor
  (:mod:`.plcopen`);
- ``codesys/arm_controller_codesys.xml`` + ``codesys/register-map.md``: the same XML with the
  located variables laid out for CODESYS's byte addressing and its Modbus server device
  (:mod:`.codesys`).

A user's program is exported under its own name (its PROGRAM, ``--name``);
``--library-only`` writes blocks and types alone as PLCopen XML for CODESYS.
``armbench export --check`` compares instead of writing. Pipeline: :mod:`.generate` runs the
checker, :mod:`.sources` orders the files, :mod:`.sttext` slices bodies and comments.
"""

from __future__ import annotations

from .generate import (
    CODESYS_FILE,
    CODESYS_MAP_FILE,
    OPENPLC_FILE,
    PLCOPEN_FILE,
    Export,
    export_paths,
    generate,
    generate_library,
    load_sources,
)
from .sources import default_sources

__all__ = ["CODESYS_FILE", "CODESYS_MAP_FILE", "OPENPLC_FILE", "PLCOPEN_FILE", "Export",
           "default_sources", "export_paths", "generate", "generate_library",
           "load_sources"]
