# SPDX-License-Identifier: LGPL-2.1-or-later
"""Set-up never destroys a user's files, and installs where each FreeCAD looks.

``tools/install_addon.py`` links the repository into the Mod folder that FreeCAD reports
(0.20 and 1.0 share ``~/.local/share/FreeCAD``, 1.1 has ``.../v1-1``).  These tests run it on
temporary folders, with a stand-in ``freecadcmd`` that answers like FreeCAD does.
"""

from __future__ import annotations

import importlib.util
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
_spec = importlib.util.spec_from_file_location("install_addon", REPO / "tools" / "install_addon.py")
install_addon = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(install_addon)


def fake_freecadcmd(folder: Path, user_data: str, noise: str = "FreeCAD 1.1.3, Libs: 1.1.3\n") -> Path:
    """An executable that, like ``freecadcmd -c CODE``, runs CODE with a stub FreeCAD module."""
    stub = folder / "stub"
    stub.mkdir(exist_ok=True)
    (stub / "FreeCAD.py").write_text(f"def getUserAppDataDir():\n    return {user_data!r}\n")
    exe = folder / "freecadcmd"
    exe.write_text(
        "#!/bin/sh\n"
        f"printf '%s' {noise!r}\n"
        f'[ "$1" = -c ] && PYTHONPATH={stub} exec {sys.executable} -c "$2"\n'
        "exit 1\n"
    )
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    return exe


def test_fresh_install_links_into_the_reported_folder(tmp_path):
    user = tmp_path / "share" / "FreeCAD" / "v1-1"
    exe = fake_freecadcmd(tmp_path, str(user) + "/")
    assert install_addon.ask_user_data_dir([str(exe)]) == user
    assert install_addon.main(["--freecadcmd", str(exe)]) == 0
    link = user / "Mod" / "BSplineCAM"
    assert link.is_symlink() and link.resolve() == REPO
    # again: nothing changes
    assert "already links" in install_addon.install(user)
    assert link.resolve() == REPO


def test_existing_addon_folder_is_moved_aside_never_deleted(tmp_path):
    user = tmp_path / "FreeCAD"
    installed = user / "Mod" / "BSplineCAM"
    (installed / "sub").mkdir(parents=True)
    (installed / "InitGui.py").write_text("# the Addon Manager's copy\n")
    (installed / "sub" / "data.txt").write_text("user data")
    message = install_addon.install(user, now=0)
    assert installed.is_symlink() and installed.resolve() == REPO
    moved = [p for p in user.iterdir() if p.name.startswith("BSplineCAM.moved-")]
    assert len(moved) == 1, list(user.iterdir())
    assert (moved[0] / "InitGui.py").read_text() == "# the Addon Manager's copy\n"
    assert (moved[0] / "sub" / "data.txt").read_text() == "user data"
    assert str(moved[0]) in message and "not deleted" in message
    # outside Mod: FreeCAD does not load the old copy as a second workbench
    assert [p.name for p in (user / "Mod").iterdir()] == ["BSplineCAM"]
    # a second folder moved in the same second gets its own name
    installed.unlink()
    installed.mkdir()
    install_addon.install(user, now=0)
    assert len([p for p in user.iterdir() if p.name.startswith("BSplineCAM.moved-")]) == 2


def test_link_to_another_checkout_is_replaced_and_its_files_kept(tmp_path):
    other = tmp_path / "other-checkout"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    user = tmp_path / "FreeCAD"
    (user / "Mod").mkdir(parents=True)
    (user / "Mod" / "BSplineCAM").symlink_to(other)
    message = install_addon.install(user)
    assert (user / "Mod" / "BSplineCAM").resolve() == REPO
    assert (other / "keep.txt").read_text() == "mine"
    assert str(other) in message


def test_missing_or_silent_freecad_is_one_line_and_status_2(tmp_path, capsys):
    assert install_addon.main(["--freecadcmd", str(tmp_path / "no-such-freecadcmd")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not found" in err[0] and "apt-get install freecad" in err[0]
    silent = tmp_path / "silent"
    silent.write_text("#!/bin/sh\necho 'Exception: no module named FreeCAD' >&2\nexit 1\n")
    silent.chmod(0o755)
    assert install_addon.main(["--freecadcmd", str(silent)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "did not report" in err[0] and "no module named FreeCAD" in err[0]
    assert not any(tmp_path.rglob("Mod"))  # nothing half-installed


def test_unwritable_user_folder_is_one_line_and_status_2(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert install_addon.main(["--user-data", str(blocker)]) == 2
    assert capsys.readouterr().err.startswith("install_addon: ")


def test_setup_script_never_removes_the_mod_folder():
    """The shell set-up links through install_addon.py and holds no ``rm -rf`` of Mod."""
    text = (REPO / "tools" / "setup.sh").read_text()
    assert "install_addon.py" in text
    for line in text.splitlines():
        if "rm -" in line and not line.lstrip().startswith("#"):
            assert "Mod" not in line, line


@pytest.mark.skipif(not os.path.exists("/usr/bin/freecadcmd"), reason="FreeCAD 0.20 not installed")
def test_real_freecad_reports_its_folder(tmp_path):
    # FreeCAD takes XDG_DATA_HOME over HOME where it is set (make fresh-check sets it)
    env = dict(os.environ, HOME=str(tmp_path), XDG_DATA_HOME=str(tmp_path / ".local" / "share"),
               XDG_CONFIG_HOME=str(tmp_path / ".config"))
    out = subprocess.run([sys.executable, str(REPO / "tools" / "install_addon.py")], env=env,
                         capture_output=True, text=True, timeout=300, check=False)
    assert out.returncode == 0, out.stderr
    link = next(tmp_path.rglob("Mod/BSplineCAM"))
    assert link.is_symlink() and link.resolve() == REPO
