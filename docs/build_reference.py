"""Build the API reference of msk as HTML with pdoc (https://pdoc.dev) from the docstrings.

    python docs/build_reference.py [--out docs/api]

Every public module of the package gets a page (the private ``_runtime`` room and ``__main__``
excepted); ``index.html`` is the package's face (:mod:`msk`). CI builds it
(``tests/test_reference.py``); the folder is not committed.
"""

from __future__ import annotations

import argparse
import pkgutil
from pathlib import Path

__all__ = ["build", "public_modules"]


def public_modules() -> list[str]:
    """Every public module of msk by dotted name (no ``_private`` part, no ``__main__``)."""
    import msk

    names = ["msk"]
    for info in pkgutil.walk_packages(msk.__path__, "msk."):
        parts = info.name.split(".")
        if any(p.startswith("_") for p in parts[1:]):
            continue
        names.append(info.name)
    return names


def build(out: Path) -> list[Path]:
    """Write the reference into ``out``; returns the HTML pages written."""
    import warnings

    import pdoc

    with warnings.catch_warnings():  # a package's submodules are also found through it
        warnings.simplefilter("ignore", UserWarning)
        pdoc.pdoc(*public_modules(), output_directory=out)
    return sorted(out.rglob("*.html"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "api")
    pages = build(parser.parse_args().out)
    print(f"{len(pages)} pages")


if __name__ == "__main__":
    main()
