"""Where command-line tools write: checked before the long work, claimed atomically, errors as one line.

Every CLI of the project (``bb2-sim``, ``bb2-launch``, ``bb2-analyze``, ``bb2-replay``, campaigns) uses these
helpers, so the exit-code contract is the same everywhere:

* 0 done; 1 the simulation diverged / the mission failed; **2 bad input or an OS error** (read-only,
  full, permission, encoding: one line naming the file); **130 interrupted** (Ctrl-C), after flushing what
  was written, no traceback.

The helpers:

* :func:`check_output_file` — before a run: refuse an existing file unless ``overwrite``, create the parent
  folder, prove a file can be created and written there (a read-only or full device fails *now*, not after
  the work).
* :func:`check_writable_dir` — the same for a folder that will receive files.
* :func:`claim_run_dir` — a run directory of one's own: ``os.mkdir`` is atomic, so two processes started in
  the same second never share one (the second gets ``<stem>_2``, then ``_3``, ...); an explicit directory
  that exists empty is claimed by creating its claim file with ``O_EXCL``.
* :func:`plain_name` — a name from an input file that becomes a file or directory name (a mission's, a fleet's, a
  campaign's): one name, never a path (``../../x`` would write outside the folder meant), and a text.
* :func:`run_cli` — run a CLI body, turning ``OSError``/``UnicodeError``/``MemoryError`` into one line and
  exit 2 and ``KeyboardInterrupt`` into exit 130.

It lives in ``bb2_sim`` (layer 1) because the lowest CLI that needs it, ``python -m bb2_sim maneuver``, is
there; it imports nothing of the project.
"""
from __future__ import annotations

import errno
import os
import socket
import sys
import time
from pathlib import Path
from typing import Callable

__all__ = ["OutputError", "EXIT_OK", "EXIT_FAILED", "EXIT_INPUT", "EXIT_INTERRUPTED", "CLAIM_FILE",
           "check_output_file", "check_writable_dir", "claim_run_dir", "os_error_line", "plain_name", "run_cli"]

EXIT_OK = 0
EXIT_FAILED = 1        #: the simulation diverged / the mission failed
EXIT_INPUT = 2         #: bad input or an OS error (one line naming the file)
EXIT_INTERRUPTED = 130  #: Ctrl-C (SIGINT)

CLAIM_FILE = ".bb2_run"
"""The file that marks a run directory as claimed (who, when); created with ``O_EXCL``."""

_PROBE_BYTES = 4096


class OutputError(OSError):
    """An output cannot be written where it was asked for (exit 2); the message names the file."""

    def __str__(self) -> str:  # OSError(msg) would print "[Errno ...]" forms; keep the one line
        return self.args[0] if self.args else ""


def os_error_line(exc: BaseException, path: str | os.PathLike | None = None) -> str:
    """``"<file>: <reason>"`` for an OS or encoding error (the file named whenever it is known)."""
    if isinstance(exc, OutputError):
        return str(exc)
    if isinstance(exc, UnicodeError):
        obj = getattr(exc, "object", b"")
        where = f"{path}: " if path else ""
        return f"{where}not valid UTF-8 text ({type(exc).__name__} at byte {getattr(exc, 'start', '?')}" \
               f"{' of ' + str(len(obj)) if isinstance(obj, (bytes, bytearray)) else ''})"
    if isinstance(exc, OSError):
        name = exc.filename if exc.filename is not None else path
        reason = exc.strerror or str(exc)
        return f"{name}: {reason}" if name is not None else reason
    return f"{type(exc).__name__}: {exc}"


def _probe_write(folder: Path, target: Path | None = None) -> None:
    """Create, write (and sync) and remove a small file in ``folder``: proves the folder takes data.  ``target``:
    the file or folder to be written, when ``folder`` is only the nearest one of its folders that exists (named
    in the message: ``/proc`` refuses ``/proc/x`` with 'No such file or directory', which alone misleads)."""
    probe = folder / f".bb2_write_probe_{os.getpid()}_{time.monotonic_ns()}"

    def refused(exc: OSError) -> OutputError:
        if target is not None and target != folder:
            which = "its folder" if target.parent == folder else "its nearest existing folder"
            return OutputError(f"cannot write {target}: {which} {folder} takes no files ({exc.strerror or exc})")
        return OutputError(f"cannot write into {folder}: {exc.strerror or exc}")

    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except OSError as exc:
        raise refused(exc) from None
    try:
        try:
            os.write(fd, b"\0" * _PROBE_BYTES)
            os.fsync(fd)
        except OSError as exc:
            raise refused(exc) from None
    finally:
        os.close(fd)
        try:
            probe.unlink()
        except OSError:
            pass


def check_writable_dir(folder: str | os.PathLike, *, create: bool = True) -> Path:
    """Make sure files can be written into ``folder`` (created with its parents when ``create``)."""
    d = Path(folder)
    if d.exists() and not d.is_dir():
        raise OutputError(f"{d} exists and is not a directory")
    if create:
        try:
            d.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"cannot create directory {d}: {exc.strerror or exc}") from None
    elif not d.is_dir():
        raise OutputError(f"directory {d} does not exist")
    _probe_write(d)
    return d


def check_output_file(path: str | os.PathLike, *, overwrite: bool = False, what: str = "output file",
                      flag: str = "--overwrite") -> Path:
    """Before a run: ``path`` may be (over)written. Refuses an existing file unless ``overwrite`` (the
    message names ``flag``), a directory in its place, and a folder that does not take data (the nearest
    existing folder on the way is probed; nothing is created)."""
    p = Path(path)
    if p.is_dir():
        raise OutputError(f"{what} {p} is a directory")
    if p.exists() or p.is_symlink():
        if not overwrite:
            raise OutputError(f"{what} {p} exists (give {flag} to replace it)")
        if not os.access(p, os.W_OK):
            raise OutputError(f"cannot overwrite {what} {p}: permission denied")
    folder = p.parent if str(p.parent) else Path(".")
    while not folder.exists() and folder != folder.parent:  # nothing is created yet: probe what exists
        folder = folder.parent
    if not folder.is_dir():
        raise OutputError(f"cannot write {what} {p}: {folder} is not a directory")
    _probe_write(folder, p)
    return p


def _write_claim(d: Path, fd: int) -> None:
    try:
        os.write(fd, (f"pid: {os.getpid()}\nhost: {socket.gethostname()}\n"
                      f"time: {time.strftime('%Y-%m-%dT%H:%M:%S%z')}\nargv: {sys.argv!r}\n").encode())
    finally:
        os.close(fd)


def _claim_existing_empty(d: Path) -> bool:
    """Claim an existing, empty directory with an ``O_EXCL`` claim file; False if someone else has it."""
    try:
        fd = os.open(d / CLAIM_FILE, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    except FileExistsError:
        return False
    except OSError as exc:
        raise OutputError(f"cannot write into {d}: {exc.strerror or exc}") from None
    _write_claim(d, fd)
    if any(e.name != CLAIM_FILE for e in os.scandir(d)):  # filled between our look and our claim
        (d / CLAIM_FILE).unlink(missing_ok=True)
        return False
    return True


MAX_NAME_CHARS = 200
"""The longest :func:`plain_name` (a file name may have 255 bytes; a date and ``_N`` are appended to it)."""


def plain_name(value: object, what: str = "name") -> str:
    """``value`` as a name that becomes a file or directory name: a text (an integer, as YAML reads ``name: 2024``,
    is taken as its digits) of one file name -- not empty, no ``/`` or ``\\``, not ``.`` or ``..``, no control
    characters, at most :data:`MAX_NAME_CHARS` characters.  :class:`ValueError` naming ``what`` otherwise (a
    float, a boolean or a list: YAML read ``1e3``, ``yes`` or ``[a]`` as one, so quote it)."""
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    if not isinstance(value, str):
        quote = (f" (YAML read a {type(value).__name__}: put the name in quotes)" if isinstance(value, (float, bool))
                 else "")
        raise ValueError(f"{what} must be a text, got {value!r}{quote}")
    if (not value.strip() or value in (".", "..") or any(c in "/\\" or ord(c) < 32 or ord(c) == 127 for c in value)
            or len(value) > MAX_NAME_CHARS):
        raise ValueError(f"{what} must be a plain name (one file name: not empty, no '/' or '\\', not '.' or '..', "
                         f"no control characters, at most {MAX_NAME_CHARS} characters), got {value!r}")
    return value


def claim_run_dir(parent: str | os.PathLike | None = None, stem: str | None = None, *,
                  path: str | os.PathLike | None = None, max_tries: int = 1000,
                  check: bool = True) -> Path:
    """Claim a run directory that no other process gets, whatever the timing.

    Either ``path`` (an explicit directory: created; if it exists it must be empty and unclaimed, else
    :class:`OutputError`), or ``parent``/``stem``: ``parent/stem``, else ``parent/stem_2``, ``stem_3`` ...
    — the first one this process creates with ``os.mkdir`` (atomic). The claimed directory holds
    :data:`CLAIM_FILE` (pid, host, time, argv). With ``check`` the directory is proven writable first.
    """
    if path is not None:
        d = Path(path)
        if check:
            check_writable_dir(d.parent)
        try:
            d.mkdir()
        except FileExistsError:
            if not d.is_dir():
                raise OutputError(f"run directory {d} exists and is not a directory") from None
            if any(True for _ in os.scandir(d)) or not _claim_existing_empty(d):
                raise OutputError(f"run directory {d} exists and is not empty (another run has it)") from None
            return d
        except OSError as exc:
            raise OutputError(f"cannot create run directory {d}: {exc.strerror or exc}") from None
        _write_claim(d, os.open(d / CLAIM_FILE, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
        return d
    if parent is None or not stem:
        raise ValueError("claim_run_dir needs path, or parent and stem")
    plain_name(stem, "claim_run_dir: stem")  # a name in parent, never a path out of it
    base = Path(parent)
    if check:
        check_writable_dir(base)
    for i in range(1, max_tries + 1):
        d = base / (stem if i == 1 else f"{stem}_{i}")
        try:
            d.mkdir()
        except FileExistsError:
            continue
        except OSError as exc:
            raise OutputError(f"cannot create run directory {d}: {exc.strerror or exc}") from None
        _write_claim(d, os.open(d / CLAIM_FILE, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
        return d
    raise OutputError(f"no free run directory {base / stem}[_N] after {max_tries} tries")


def run_cli(prog: str, body: Callable[[], int], *, path_hint: str | os.PathLike | None = None) -> int:
    """Run a CLI body with the exit-code contract: OS/encoding errors -> one line naming the file, exit 2;
    MemoryError -> one line, exit 2; Ctrl-C -> "interrupted", exit 130 (``finally`` blocks of the body have
    flushed and closed its files by then)."""
    try:
        return body()
    except KeyboardInterrupt:
        print(f"\n{prog}: interrupted", file=sys.stderr, flush=True)
        return EXIT_INTERRUPTED
    except (OSError, UnicodeError) as exc:
        print(f"{prog}: error: {os_error_line(exc, path_hint)}", file=sys.stderr, flush=True)
        return EXIT_INPUT
    except MemoryError as exc:  # (check_fits_in_memory says what and how much; Python's own has no message)
        print(f"{prog}: error: {exc or 'out of memory'}", file=sys.stderr, flush=True)
        return EXIT_INPUT
    finally:
        try:
            sys.stdout.flush()
        except (OSError, ValueError):
            pass


def is_no_space(exc: BaseException) -> bool:
    """True for a full device (ENOSPC, EDQUOT)."""
    return isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT)


def available_memory_bytes() -> int | None:
    """MemAvailable of /proc/meminfo (bytes), or None where it cannot be read."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def check_fits_in_memory(nbytes: float, what: str, *, fraction: float = 0.5) -> None:
    """Raise ``MemoryError`` (one line: what, how much, how much is free) when ``nbytes`` exceeds ``fraction``
    of the available memory: refuse up front instead of growing without bound."""
    avail = available_memory_bytes()
    if avail is not None and nbytes > fraction * avail:
        raise MemoryError(f"{what} would need about {nbytes / 2**30:.1f} GiB in memory, more than "
                          f"{fraction:.0%} of the {avail / 2**30:.1f} GiB available")
