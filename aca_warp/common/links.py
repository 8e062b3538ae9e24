"""Files aca-warp creates beside its outputs, opened so that no link planted in a shared folder redirects them.

Another user who can write into a folder where a run writes (a shared project folder, ``/tmp``) can plant a
symbolic link where aca-warp will create a lock, a temporary or a figure file (``run.h5.lock → /some/file``); a
plain ``open(path, "w")`` would then truncate and overwrite ``/some/file`` with the runner's rights. Every such
file is therefore opened here without following a link (``O_NOFOLLOW``) and, where it is new, created exclusively
(``O_CREAT | O_EXCL``: a name that exists, a link included, is never reused); a link found at one of these names
is refused with one line (:class:`LinkError`, exit 2) and left alone, so the file it
points to is never touched (docs/faults.md, "Threat model").

Files that belong to one user's processes only (the GPU turn lock of sweeps, the identity locks of
:class:`~aca_warp.common.files.OutputLock`) live in :func:`private_dir`, a folder the user owns with mode 0700,
not in the shared temporary folder.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from aca_warp.common.errors import SceneError

NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


class LinkError(SceneError):
    """A link (or another non-file) found where aca-warp creates one of its own files; exit 2, nothing written
    through it. Not a skippable error: a command that skips what it cannot make (``plot``) stops on it."""


def link_refusal(path: Path, what: str) -> LinkError:
    """The one-line refusal of a link (or another non-file) found where aca-warp creates ``what``."""
    try:
        target = f" (to {os.readlink(path)})" if os.path.islink(path) else ""
    except OSError:
        target = ""
    kind = "a symbolic link" if target or os.path.islink(path) else "not a plain file of its own"
    return LinkError(
        f"{path} is {kind}{target}; aca-warp creates its {what} there and never writes through a link: remove it "
        "(and check who planted it)"
    )


def open_lock_file(path: Path, what: str = "lock file", mode: int = 0o644) -> int:
    """Open (or create) the lock file ``path`` read-write without following a link; returns the descriptor.

    Refused (:func:`link_refusal`): a symbolic link, anything but a regular file, a file with more than one name
    (a hard link to another file). A file with no name left (its holder removed it between this open and the check,
    as a release does) is opened anew. Other OSErrors pass through (the caller names the folder)."""
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NONBLOCK | NOFOLLOW, mode)
        except OSError as e:
            if e.errno == errno.ELOOP:
                raise link_refusal(path, what) from None
            raise
        st = os.fstat(fd)
        if stat.S_ISREG(st.st_mode) and st.st_nlink == 0:  # its holder removed it after our open: open anew
            os.close(fd)
            continue
        if not stat.S_ISREG(st.st_mode) or st.st_nlink != 1:
            os.close(fd)
            raise link_refusal(path, what)
        return fd


def clear_name(path: Path, what: str) -> None:
    """Make ``path`` free for a new ``what``: a regular file left there (by an earlier, killed process) is removed; a
    symbolic link or another kind of file is refused (:func:`link_refusal`) and left alone. The creation that
    follows must be exclusive (:func:`create_new`, or HDF5's ``mode="x"``), so a name that reappears in between is
    refused too, never followed."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    if not stat.S_ISREG(st.st_mode):
        raise link_refusal(path, what)
    os.unlink(path)  # removes a name, never follows one


def create_new(path: Path, what: str, mode: int = 0o644) -> int:
    """Create ``path`` as a new, empty file for writing (:func:`clear_name`, then ``O_CREAT | O_EXCL |
    O_NOFOLLOW``); returns its descriptor."""
    clear_name(path, what)
    try:
        return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC | NOFOLLOW, mode)
    except FileExistsError:
        raise link_refusal(path, what) from None


def private_dir(*parts: str) -> Path:
    """A folder only this user can enter (mode 0700, owned by the user, not a link): ``$XDG_RUNTIME_DIR/aca-warp``
    when that folder exists, else ``$XDG_CACHE_HOME/aca_warp`` (``~/.cache/aca_warp``), with ``parts`` below it; created
    when missing. OSError when it cannot be created or is not private (another owner, a link, other users' access)."""
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime and os.path.isabs(runtime) and os.path.isdir(runtime):
        base = Path(runtime) / "aca-warp"
    else:
        cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        base = Path(cache) / "aca_warp"
    d = base.joinpath(*parts)
    for p in [base, *(base.joinpath(*parts[: i + 1]) for i in range(len(parts)))]:
        p.parent.mkdir(parents=True, exist_ok=True)
        try:
            os.mkdir(p, 0o700)
        except FileExistsError:
            pass
        st = os.lstat(p)
        if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.geteuid():
            raise OSError(errno.EPERM, f"{p} is not a folder of this user", str(p))
        if st.st_mode & 0o077:
            os.chmod(p, 0o700)  # ours: make it private
    return d
