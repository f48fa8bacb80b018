"""The data-loss cases of issue 28: a command refuses a folder that is not a workspace, cleans
only what it wrote, never replaces what an output path must not replace, rebuilds a lost
``config.yaml`` from the stage records and refuses a symlinked stage folder, each as the user
meets it. Registered in :data:`tests.faults.cases.CASES` (imported at the end of that module).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import socket
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from rapomdp.workspace import MARKER, SCRATCH
from tests.faults.cases import case
from tests.faults.harness import Outcome, cached_workspace, cli, lost_files, snapshot
from tests.planning.planning_fixtures import TIGER

#: Every stage's command, as a user runs it on a folder.
STAGE_COMMANDS = ("dataset", "render", "xrho", "train", "classifier_eval", "saliency", "volume",
                  "observe", "vptree", "robot", "solve", "learn", "evaluate")


def tree(root: Path) -> dict[str, str]:
    """Everything under ``root`` (itself included): each file's SHA-256 (``.lock`` too), each
    link's target, each other entry's kind; what a command must leave as it was."""
    if not os.path.lexists(root):
        return {}
    found = {}
    for path in [root, *sorted(root.rglob("*"))]:
        mode = os.lstat(path).st_mode
        name = str(path.relative_to(root))
        if stat.S_ISLNK(mode):
            found[name] = f"link -> {os.readlink(path)}"
        elif stat.S_ISREG(mode):
            found[name] = hashlib.sha256(path.read_bytes()).hexdigest()
        else:
            found[name] = stat.filemode(mode)[0]
    return found


def _unchanged(outcome: Outcome, before: dict[str, str], root: Path) -> Outcome:
    """``outcome`` with every entry under ``root`` that was lost, changed or added."""
    after = tree(root)
    outcome.lost = sorted(lost_files(before, after) + [f"{k} (added)" for k in after
                                                       if k not in before])
    return outcome


def user_folder(root: Path) -> Path:
    """``root/ws``: an ordinary folder of a user's, with folders named like stages, files and
    folders named like a run's leftovers, a ``.lock`` of their own and a ``.photos.old-7``."""
    folder = root / "ws"
    for name in ("train", "dataset", "render", "report", "solve", "evaluate", ".cache.tmp-3",
                 ".photos.old-7"):
        (folder / name).mkdir(parents=True)
        (folder / name / "notes.txt").write_text(f"the user's {name}\n")
    (folder / ".x.tmp").write_text("draft\n")
    (folder / ".lock").write_text("the user's lock\n")
    return folder


def _refused(root: Path, args: list[str], folder: Path | None = None) -> Outcome:
    """``args`` (``{W}`` the folder) on a user's folder: refused, nothing touched."""
    folder = folder or user_folder(root)
    before = tree(folder)
    outcome = cli([str(folder) if arg == "{W}" else arg for arg in args])
    return _unchanged(outcome, before, folder)


@contextmanager
def _cwd(folder: Path) -> Iterator[None]:
    previous = Path.cwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(previous)


# -- a folder that is not a workspace --------------------------------------------------------

@case("not a workspace: run", "`rapomdp run -w DIR` on a user's folder (train/, dataset/, "
      ".x.tmp, .lock, .photos.old-7)", "not a rapomdp workspace")
def run_on_a_user_folder(root: Path) -> Outcome:
    outcome = _refused(root, ["run", "-w", "{W}"])
    assert str(root / "ws") in outcome.message, outcome.message
    return outcome


@case("not a workspace: report", "`rapomdp report -w DIR` on a user's folder",
      "not a rapomdp workspace")
def report_on_a_user_folder(root: Path) -> Outcome:
    return _refused(root, ["report", "-w", "{W}"])


@case("not a workspace: stages", "every stage's command and `figure fig1|fig2` on a user's "
      "folder", "not a rapomdp workspace")
def stages_on_a_user_folder(root: Path) -> Outcome:
    folder = user_folder(root)
    before = tree(folder)
    outcome = Outcome(0, "")
    for args in ([[name, "-w", str(folder)] for name in STAGE_COMMANDS]
                 + [["figure", "fig1", "-w", str(folder)],
                    ["figure", "fig2", "-w", str(folder), "--target", "cup", "--against",
                     "mug"]]):
        outcome = cli(args)
        assert outcome.exit_code == 2 and "not a rapomdp workspace" in outcome.message, (
            args, outcome.detail)
    return _unchanged(outcome, before, folder)


@case("-w ''", "`rapomdp run -w ''` (an unset variable) in a user's folder",
      "--workspace is empty")
def empty_workspace_argument(root: Path) -> Outcome:
    folder = user_folder(root)
    before = tree(folder)
    with _cwd(folder):
        outcome = cli(["run", "-w", ""])
    return _unchanged(outcome, before, folder)


@case("-w .", "`rapomdp render -w .` in a user's folder", "not a rapomdp workspace")
def dot_workspace(root: Path) -> Outcome:
    folder = user_folder(root)
    before = tree(folder)
    with _cwd(folder):
        outcome = cli(["render", "-w", "."])
    assert outcome.message.startswith(f"error: {folder}: "), outcome.message  # named in full
    return _unchanged(outcome, before, folder)


@case("manifest of another program", "a folder whose manifest.json is a web app's",
      "its manifest.json is not a rapomdp manifest")
def foreign_manifest(root: Path) -> Outcome:
    folder = root / "ws"
    folder.mkdir()
    (folder / "manifest.json").write_text('{"name": "my app", "icons": []}\n')
    (folder / "index.html").write_text("<html></html>\n")
    return _refused(root, ["run", "-w", "{W}"], folder)


@case("-w FILE", "`rapomdp run -w FILE`, a regular file", "not a folder")
def workspace_is_a_file(root: Path) -> Outcome:
    path = root / "ws"
    path.write_text("a file of the user's\n")
    before = tree(path)
    return _unchanged(cli(["run", "-w", str(path)]), before, path)


@case("-w symlink loop", "`rapomdp run -w LINK`, a symbolic link to itself",
      "too many levels of symbolic links")
def workspace_symlink_loop(root: Path) -> Outcome:
    link = root / "ws"
    link.symlink_to(link)
    outcome = cli(["run", "-w", str(link)])
    assert os.readlink(link) == str(link)
    return outcome


@case("newer workspace format", "a workspace whose marker names format 99",
      "made by a newer rapomdp")
def newer_format(root: Path) -> Outcome:
    ws = cached_workspace(root)
    (ws / MARKER).write_text('{"format": 99}\n')
    before = tree(ws)
    return _unchanged(cli(["render", "-w", str(ws)]), before, ws)


@case("empty folder", "`rapomdp dataset -w DIR` on an empty folder: a new workspace",
      "dataset    done", succeeds=True)
def empty_folder_becomes_a_workspace(root: Path) -> Outcome:
    folder = root / "ws"
    folder.mkdir()
    (root / "input").mkdir()
    config = root / "input" / "c.yaml"
    config.write_text("seed: 3\ndataset: {classes: [cup, mug], split: {train: 1, volume: 1, "
                      "test: 1}}\n")
    outcome = cli(["dataset", "-w", str(folder), "-c", str(config)])
    assert json.loads((folder / MARKER).read_text())["format"] == 1
    outcome.message = next(line for line in outcome.detail.splitlines() if "dataset " in line)
    return outcome


@case("workspace without marker", "a workspace made before markers (a valid manifest), then "
      "`render`", "cached", succeeds=True)
def older_workspace_gets_its_marker(root: Path) -> Outcome:
    ws = cached_workspace(root)
    (ws / MARKER).unlink()
    before = snapshot(ws)
    outcome = cli(["render", "-w", str(ws)])
    assert (ws / MARKER).is_file(), "written at its first locked run"
    outcome.message = outcome.detail.strip().splitlines()[-1]
    outcome.lost = lost_files(before, snapshot(ws))
    return outcome


# -- cleanup touches only what a run wrote ---------------------------------------------------

@case("user files named like leftovers", "a workspace holding .x.tmp, .photos.old-7/, "
      ".render.old-5/, .dataset.tmp-3/ of the user's, then `render`", "cached", succeeds=True)
def leftover_names_of_the_user(root: Path) -> Outcome:
    ws = cached_workspace(root)
    for name in (".photos.old-7", ".render.old-5", ".dataset.tmp-3"):
        (ws / name).mkdir()
        (ws / name / "keep.txt").write_text(name)
    (ws / ".x.tmp").write_text("draft\n")
    before = tree(ws)
    outcome = cli(["render", "-w", str(ws)])
    outcome.message = outcome.detail.strip().splitlines()[-1]
    outcome.lost = [k for k in lost_files(before, tree(ws)) if k != ".lock"]
    assert not (ws / "photos").exists()
    return outcome


@case("old version's symlinked .render.old-PID", "a `.render.old-PID` symlink an older "
      "version left (it printed `(unknown file): OSError` ever after), then `render`",
      "cached", succeeds=True)
def old_symlink_leftover(root: Path) -> Outcome:
    ws = cached_workspace(root)
    elsewhere = root / "input" / "render-copy"
    shutil.copytree(ws / "render", elsewhere)
    (ws / ".render.old-4242").symlink_to(elsewhere)
    before = tree(root / "input")
    outcome = cli(["render", "-w", str(ws)])
    assert os.readlink(ws / ".render.old-4242") == str(elsewhere), "not ours to touch"
    outcome.message = outcome.detail.strip().splitlines()[-1]
    return _unchanged(outcome, before, root / "input")


def _own_name_linked(root: Path, name: str, folder: bool) -> Outcome:
    """W/``name`` (the workspace's lock or scratch folder) a symbolic link to a user's file or
    folder, then `render`: refused by name, nothing emptied or truncated through the link."""
    ws = cached_workspace(root)
    precious = root / "input" / "precious"
    precious.parent.mkdir()
    if folder:
        precious.mkdir()
        (precious / "thesis.tex").write_text("years of work\n")
    else:
        precious.write_text("years of work\n")
    if os.path.lexists(ws / name):
        os.unlink(ws / name)
    (ws / name).symlink_to(precious)
    before, outside = snapshot(ws), tree(precious)
    outcome = cli(["render", "-w", str(ws)])
    outcome.lost = lost_files(before, snapshot(ws)) + [
        f"input/precious/{k}" for k in lost_files(outside, tree(precious))]
    return outcome


@case("scratch folder a symlink", f"W/{SCRATCH} a symbolic link to a user's folder, then "
      "`render`", f"{SCRATCH}: a symbolic link")
def scratch_linked(root: Path) -> Outcome:
    return _own_name_linked(root, SCRATCH, folder=True)


@case(".lock a symlink", "W/.lock a symbolic link to a user's file, then `render`",
      ".lock: a symbolic link")
def lock_linked(root: Path) -> Outcome:
    return _own_name_linked(root, ".lock", folder=False)


# -- a stage folder that is a symbolic link --------------------------------------------------

@case("symlinked stage --force", "W/render a symbolic link to a folder elsewhere, then "
      "`render --force`, then `status` and `render`", "a symbolic link")
def symlinked_stage_forced(root: Path) -> Outcome:
    ws = cached_workspace(root)
    elsewhere = root / "input" / "render"
    elsewhere.parent.mkdir()
    os.replace(ws / "render", elsewhere)
    (ws / "render").symlink_to(elsewhere)
    before, outside = tree(ws), tree(elsewhere)
    outcome = cli(["render", "-w", str(ws), "--force"])
    for args in (["status", "-w", str(ws)], ["render", "-w", str(ws)]):
        later = cli(args)
        assert later.exit_code == 0, (args, later.detail)
    leftovers = [p.name for p in ws.iterdir() if ".old-" in p.name or p.name == SCRATCH]
    assert not leftovers, leftovers
    _unchanged(outcome, before, ws)
    outcome.lost = [k for k in outcome.lost if k != ".lock"]
    outcome.lost += [f"input/render/{k}" for k in lost_files(outside, tree(elsewhere))]
    return outcome


@case("user folder at a stage's path", "a workspace where the user made W/robot/ (no "
      "stage record), then `robot`", "a folder rapomdp did not make")
def user_folder_at_stage_path(root: Path) -> Outcome:
    ws = cached_workspace(root)
    (ws / "robot").mkdir()
    (ws / "robot" / "notes.txt").write_text("the user's\n")
    before = tree(ws)
    outcome = cli(["robot", "-w", str(ws)])
    outcome = _unchanged(outcome, before, ws)
    outcome.lost = [k for k in outcome.lost if k != ".lock"]
    return outcome


# -- config.yaml lost ------------------------------------------------------------------------

@case("config.yaml deleted", "W/config.yaml deleted, then `rapomdp dataset -w W` (no "
      "--reconfigure)", "rebuilt from the stage records", succeeds=True)
def config_deleted(root: Path) -> Outcome:
    ws = cached_workspace(root)
    (ws / "config.yaml").unlink()
    before = snapshot(ws)
    outcome = cli(["dataset", "-w", str(ws)])
    lines = outcome.detail.splitlines()
    assert any("dataset    cached" in line for line in lines), outcome.detail
    restored = (ws / "config.yaml").read_text()
    assert "- bicycle" in restored and "seed: 3" in restored, restored
    outcome.message = next(line for line in lines if line.startswith("note:"))
    outcome.lost = lost_files(before, snapshot(ws))
    return outcome


# -- output paths ----------------------------------------------------------------------------

def _output_refused(root: Path, make: str, args: list[str], ws: Path | None = None) -> Outcome:
    """``args`` with ``{OUT}`` a path under ``root/input`` that is ``make`` (fifo, folder,
    socket, link): refused by name, the path and its folder as they were."""
    folder = root / "input"
    folder.mkdir(exist_ok=True)
    out = folder / "out.npz"
    if make == "fifo":
        os.mkfifo(out)
    elif make == "folder":
        out.mkdir()
    elif make == "link":
        (folder / "target.png").write_text("the user's file\n")
        out.symlink_to(folder / "target.png")
    listener = None
    if make == "socket":
        listener = socket.socket(socket.AF_UNIX)
        with _cwd(folder):  # a short relative name: socket paths are limited to 108 bytes
            listener.bind(out.name)
    if "{TIGER}" in args:
        (folder / "tiger.pomdp").write_text(TIGER)
    before = tree(folder)
    ws_before = snapshot(ws) if ws is not None else {}
    try:
        outcome = cli([str(out) if a == "{OUT}" else str(folder / "tiger.pomdp")
                       if a == "{TIGER}" else a for a in args])
    finally:
        if listener is not None:
            listener.close()
    _unchanged(outcome, before, folder)
    if ws is not None:
        outcome.lost += lost_files(ws_before, snapshot(ws))
    return outcome


@case("pomdp solve --out FIFO", "`pomdp solve tiger.pomdp --out P`, P a named pipe (as a "
      "device would be)", "a named pipe (FIFO), not a regular file")
def solve_out_fifo(root: Path) -> Outcome:
    return _output_refused(root, "fifo", ["pomdp", "solve", "{TIGER}", "--out", "{OUT}"])


@case("pomdp export --out folder", "`pomdp export --benchmark 4x2 --out D`, D a folder",
      "a folder, not a regular file")
def export_out_folder(root: Path) -> Outcome:
    return _output_refused(root, "folder", ["pomdp", "export", "--benchmark", "4x2", "--out",
                                            "{OUT}"])


@case("pomdp export --out FIFO", "`pomdp export --benchmark 4x2 --out P`, P a named pipe",
      "a named pipe (FIFO)")
def export_out_fifo(root: Path) -> Outcome:
    return _output_refused(root, "fifo", ["pomdp", "export", "--benchmark", "4x2", "--out",
                                          "{OUT}"])


@case("dataset preview --out socket", "`dataset preview --out S`, S a Unix socket",
      "a socket, not a regular file")
def preview_out_socket(root: Path) -> Outcome:
    ws = cached_workspace(root)
    return _output_refused(root, "socket", ["dataset", "preview", "-w", str(ws), "--width",
                                            "32", "--out", "{OUT}"], ws)


@case("dataset preview --out symlink", "`dataset preview --out L`, L a symbolic link to a "
      "file of the user's", "a symbolic link, not a regular file")
def preview_out_link(root: Path) -> Outcome:
    ws = cached_workspace(root)
    return _output_refused(root, "link", ["dataset", "preview", "-w", str(ws), "--width",
                                          "32", "--out", "{OUT}"], ws)


@case("report --readme FIFO", "`report --readme P`, P a named pipe (it would block a read)",
      "a named pipe (FIFO)")
def readme_fifo(root: Path) -> Outcome:
    ws = cached_workspace(root)
    return _output_refused(root, "fifo", ["report", "-w", str(ws), "--readme", "{OUT}"], ws)


@case("dataset preview --out file", "`dataset preview --out F`, F an existing regular file "
      "(replaced, no temporary left beside it)", "contact sheet written", succeeds=True)
def preview_out_regular(root: Path) -> Outcome:
    ws = cached_workspace(root)
    folder = root / "input"
    folder.mkdir()
    out = folder / "sheet.png"
    out.write_text("an older sheet\n")
    outcome = cli(["dataset", "preview", "-w", str(ws), "--width", "32", "--out", str(out)])
    assert out.read_bytes().startswith(b"\x89PNG"), "replaced"
    assert sorted(p.name for p in folder.iterdir()) == ["sheet.png"]
    outcome.message = outcome.detail.strip().splitlines()[-1]
    return outcome
