"""Build hook: the wheel carries the ST library and the controller program as package data.

st/ and plc_project/ stay the single source in the repository (no second copy in git); this
copies st/*.st, plc_project/Controller.st and plc_project/controller/*.st into ``armbench/_data/`` of the build, where
:mod:`armbench.locate` finds them in an installed package. An editable install maps the
package to sim/armbench and uses the checkout's own files, so nothing is copied then.
Everything else is in pyproject.toml.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
# (source glob relative to the repository, destination folder relative to armbench/_data)
BUNDLED = (("st/*.st", "st"), ("plc_project/Controller.st", "plc_project"),
           ("plc_project/controller/*.st", "plc_project/controller"))


class BuildPyWithProject(build_py):
    def run(self) -> None:
        super().run()
        if self.editable_mode:
            return
        data = Path(self.build_lib) / "armbench" / "_data"
        shutil.rmtree(data, ignore_errors=True)  # build/ may hold files deleted since
        for pattern, dest in BUNDLED:
            files = sorted(HERE.glob(pattern))
            if not files:
                raise FileNotFoundError(f"{HERE / pattern}: the wheel must carry it; build "
                                        "from a full checkout or sdist")
            (data / dest).mkdir(parents=True, exist_ok=True)
            for f in files:
                shutil.copyfile(f, data / dest / f.name)


setup(cmdclass={"build_py": BuildPyWithProject})
