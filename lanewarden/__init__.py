"""Lanewarden's composition root: the CLI, the one config, and the robot runner.

This is the only package that imports perception, supervisor, actuation and scenarios together.

Installed, `lanewarden.perception` ... are folders inside this package (pyproject.toml's
package-dir mapping). Imported from a clone's root without an editable install (`python
benchmarks/...`, `python -m lanewarden.config_reference` after `pip install .`: the clone's
`lanewarden/` folder comes first on sys.path and hides the installed copy), they are the clone's
`perception/`, `supervisor/`, ... folders beside this one: the clone's root joins this package's
search path, so the clone is imported whole, never half the clone and half an installed copy.
"""

from pathlib import Path as _Path

__version__ = "0.1.0"

_HERE = _Path(__file__).resolve().parent
_CLONE = _HERE.parent
if (not (_HERE / "perception").is_dir() and (_CLONE / "pyproject.toml").is_file()
        and (_CLONE / "perception" / "__init__.py").is_file()
        and str(_CLONE) not in __path__):
    __path__.append(str(_CLONE))
