"""Where the ST library and the controller program are, for the tools and for the generators.

Two different questions, kept apart on purpose:

- :func:`default_project` -- the files the tools *use* (``check``, ``run``, ``serve``,
  ``export``, the pytest plugin, the demo). An installed wheel carries copies of ``st/*.st``
  and ``plc_project/Controller.st`` in ``armbench/_data/`` (the build copies them from the
  repository, see ``setup.py``); run from a checkout or an editable install, the package
  sits in ``<checkout>/sim/armbench`` and the checkout's own files are used.
- :func:`find_checkout` -- the repository a generator *writes into* (``armbench export
  --regenerate``, batchgen, docgen, lutgen, registermap, the teaching plots): given with
  ``--repo``, or found from the current directory upwards. Never the installed package.

:func:`with_library` pairs a user's program with the library files its names are looked up in.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
DATA_DIR = PACKAGE_DIR / "_data"  # filled by the wheel build; absent in a checkout
CONTROLLER_REL = Path("plc_project") / "Controller.st"
# The controller's function blocks (mailbox server, output stage, ...): one file each.
COMPONENTS_REL = Path("plc_project") / "controller"


class LocateError(Exception):
    """The library, the controller or a checkout cannot be found; the message says why."""


class NotACheckout(LocateError):
    """A generator was run outside a checkout of the armbench repository."""


@dataclass(frozen=True)
class Project:
    """A folder holding ``st/*.st`` and ``plc_project/Controller.st``."""

    root: Path

    @property
    def st_dir(self) -> Path:
        return self.root / "st"

    @property
    def plc_project(self) -> Path:
        return self.root / "plc_project"

    @property
    def controller(self) -> Path:
        return self.root / CONTROLLER_REL

    def library(self) -> list[Path]:
        """st/*.st, sorted by name."""
        return sorted(self.st_dir.glob("*.st"))

    def components(self) -> list[Path]:
        """plc_project/controller/*.st, sorted by name: the blocks the controller PROGRAM is
        composed of, usable in a user's own program too."""
        return sorted((self.root / COMPONENTS_REL).glob("*.st"))

    def sources(self) -> list[Path]:
        """The library, the controller's blocks, then the controller: what the OpenPLC export
        and the demo compile."""
        return [*self.library(), *self.components(), self.controller]

    def relative(self, path: Path) -> str | None:
        """``path`` relative to the root (``st/ArmAngles.st``), or None when outside it."""
        try:
            return path.resolve().relative_to(self.root.resolve()).as_posix()
        except ValueError:
            return None


def _is_project(root: Path) -> bool:
    return (root / "st").is_dir() and (root / CONTROLLER_REL).is_file()


def _is_checkout(root: Path) -> bool:
    return _is_project(root) and (root / "pyproject.toml").is_file()


def package_checkout() -> Project | None:
    """The checkout this package is imported from (``<root>/sim/armbench``: running from the
    source tree or an editable install), or None for an installed package."""
    sim = PACKAGE_DIR.parent
    if sim.name != "sim" or not _is_checkout(sim.parent):
        return None
    return Project(sim.parent)


def default_project() -> Project:
    """The library and controller the tools use: the wheel's copies, else the checkout's."""
    if _is_project(DATA_DIR):
        return Project(DATA_DIR)
    checkout = package_checkout()
    if checkout is not None:
        return checkout
    raise LocateError(
        f"armbench's ST library is missing: {DATA_DIR} has no st/*.st and "
        "plc_project/Controller.st, and the package is not inside a checkout; reinstall it "
        "with `pip install <armbench wheel or source folder>`")


def find_checkout(repo: str | Path | None = None, start: Path | None = None) -> Project:
    """The repository a generator writes into: ``repo`` if given, else the first folder from
    ``start`` (default: the current directory) upwards holding pyproject.toml, st/ and
    plc_project/Controller.st."""
    if repo is not None:
        root = Path(repo)
        if not _is_checkout(root):
            raise NotACheckout(f"{root} is not a checkout of the armbench repository (it needs "
                               "pyproject.toml, st/ and plc_project/Controller.st)")
        return Project(root)
    here = (start or Path.cwd()).resolve()
    for root in (here, *here.parents):
        if _is_checkout(root):
            return Project(root)
    raise NotACheckout(f"{here} is not inside a checkout of the armbench repository: this "
                       "command rewrites the repository's own files; run it from your clone "
                       "(or pass --repo DIR)")


@dataclass(frozen=True)
class LibrarySelection:
    """A program's files and the library files its names are looked up in: the compiler takes
    from those only the declarations the program uses (armbench.compiler.uses)."""

    given: list[Path]
    library: list[Path] = field(default_factory=list)


def select_library(given: Sequence[Path], library: bool = True) -> LibrarySelection:
    """What ``armbench check/run/serve/export`` and the pytest plugin compile ``given`` with:
    the armbench ST library and the controller's blocks (plc_project/controller/*.st), taken by
    use, less the files ``given`` replaces; nothing when ``library`` is False."""
    if not library:
        return LibrarySelection(list(given))
    project = default_project()
    return with_library(given, [*project.library(), *project.components()])


def with_library(given: Sequence[Path], library: Sequence[Path]) -> LibrarySelection:
    """``given`` and the library files they do not replace: a library file is left out when a
    given file is the same file or has the same name (the user's own modified copy)."""
    given_res = {p.resolve() for p in given}
    given_names = {p.name.lower() for p in given}
    return LibrarySelection(list(given), [lib for lib in library
                                          if lib.resolve() not in given_res
                                          and lib.name.lower() not in given_names])
