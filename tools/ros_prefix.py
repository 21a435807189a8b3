"""The project's venv as a ROS prefix of the mechsim package, as `colcon build --symlink-install`
would make a workspace's (tools/bootstrap.py's step ``ros-package``; stdlib only).

What setup.cfg declares for colcon and pip is what is made here, so the two never differ:
its ``[options.data_files]`` (the ament index marker, ``share/mechsim/{package.xml,launch,
scenes,config}``) linked file by file to the checkout (directories of links: ``ros2 launch``
walks the share directory without following directory links), and its entry point group
``mechsim.executables`` as scripts under ``lib/mechsim``, where ``ros2 run`` and launch_ros look
for a package's executables. The venv's ``bin`` keeps only ``mechsim``.
"""

from __future__ import annotations

import configparser
import hashlib
import shutil
from collections.abc import Callable
from pathlib import Path


def setup_cfg(root: Path, section: str) -> dict[str, str]:
    """One section of setup.cfg, as key -> value text."""
    cfg = configparser.ConfigParser()
    cfg.optionxform = str  # type: ignore[assignment,method-assign]
    cfg.read(root / "setup.cfg", encoding="utf-8")
    return dict(cfg[section]) if cfg.has_section(section) else {}


def node_executables(root: Path) -> dict[str, str]:
    """name -> "module:function" of setup.cfg's entry point group mechsim.executables."""
    text = setup_cfg(root, "options.entry_points").get("mechsim.executables", "")
    pairs = (line.split("=", 1) for line in text.splitlines() if "=" in line)
    return {name.strip(): target.strip() for name, target in pairs}


def data_files(root: Path) -> dict[str, list[Path]]:
    """setup.cfg's [options.data_files]: directory under the prefix -> the checkout's files
    (globs expanded)."""
    out: dict[str, list[Path]] = {}
    for target, patterns in setup_cfg(root, "options.data_files").items():
        out[target] = sorted(p for pattern in patterns.replace(",", " ").split()
                             for p in root.glob(pattern) if p.is_file())
    return out


def key(root: Path, extra: str) -> str:
    """What the prefix is made from: setup.cfg and the names of the files it installs (a file
    added or removed remakes it; their contents are linked, never copied)."""
    h = hashlib.sha256(f"{extra}|{root}".encode())
    h.update((root / "setup.cfg").read_bytes())
    for group in data_files(root).values():
        for p in group:
            h.update(str(p.relative_to(root)).encode() + b"\0")
    return h.hexdigest()[:16]


def replace_path(path: Path, make: Callable[[Path], None]) -> None:
    """Make ``path`` anew through a temporary beside it and one rename (a directory in the
    way, made here before, is removed first)."""
    tmp = path.with_name(f".{path.name}.tmp")
    if tmp.is_dir() and not tmp.is_symlink():
        shutil.rmtree(tmp)
    elif tmp.is_symlink() or tmp.exists():
        tmp.unlink()
    make(tmp)
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    tmp.replace(path)


def _linked_files(files: list[Path]) -> Callable[[Path], None]:
    def make(tmp: Path) -> None:
        tmp.mkdir()
        for f in files:
            (tmp / f.name).symlink_to(f)
    return make


def _script(python: Path, name: str, target: str) -> Callable[[Path], None]:
    module, _, function = target.partition(":")
    text = (f"#!{python}\n# The mechsim node executable {name!r} (`ros2 run mechsim {name}`)."
            f"\nimport sys\n\nfrom {module} import {function}\n\n"
            f"if __name__ == \"__main__\":\n    sys.exit({function}())\n")

    def write(tmp: Path) -> None:
        tmp.write_text(text)
        tmp.chmod(0o755)
    return write


def install(root: Path, prefix: Path, python: Path) -> None:
    """Make ``prefix`` (the venv) a ROS prefix of the package in ``root``; its executables
    run ``python``."""
    for target, files in data_files(root).items():
        where = prefix / target
        if target.startswith("share/mechsim/"):  # whole directories of the package: anew
            where.parent.mkdir(parents=True, exist_ok=True)
            replace_path(where, _linked_files(files))
            continue
        where.mkdir(parents=True, exist_ok=True)  # shared ones (the ament index): its files
        for f in files:
            replace_path(where / f.name, lambda tmp, f=f: tmp.symlink_to(f))
    lib = prefix / "lib" / "mechsim"
    lib.mkdir(parents=True, exist_ok=True)
    for name, target in node_executables(root).items():
        replace_path(lib / name, _script(python, name, target))
