"""File helpers: atomic writes, output directories as a unit, strict reading of documents.

Every document a user gives (scenario, parameter file) is read the same way by
:func:`load_document`: a regular file of at most :data:`MAX_DOCUMENT_BYTES`, decoded as
UTF-8, parsed by a YAML loader that refuses duplicate keys (or by ``json`` with the
same rule), with every failure raised as a :class:`gracenav.errors.ConfigError` whose
message names the file.
"""

from __future__ import annotations

import json
import os
import re
import tempfile
from pathlib import Path
from typing import Any

import yaml

from gracenav.errors import ConfigError

__all__ = [
    "MAX_DOCUMENT_BYTES",
    "OUTPUT_NAMES",
    "OutputDir",
    "StrictLoader",
    "atomic_write_bytes",
    "atomic_write_text",
    "check_output_dir",
    "load_document",
    "parse_yaml",
    "read_text_file",
    "yaml_error_message",
]

MAX_DOCUMENT_BYTES = 1 << 20
"""Largest scenario or parameter file read (1 MiB): such files are a few hundred bytes."""


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temporary file in the same folder, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        # mkstemp creates the file 0600; give it the permissions a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    atomic_write_bytes(path, text.encode("utf-8"))


def yaml_error_message(exc: Exception) -> str:
    """A short, one-line description of a PyYAML error with its line and column."""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    mark = getattr(exc, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    return f"{problem}{where}"


class StrictLoader(yaml.SafeLoader):
    """YAML safe loader that refuses duplicate mapping keys and reads ``1e3`` as a number.

    PyYAML (YAML 1.1) silently keeps the last of two equal keys and reads ``1e3`` (no
    dot) as the string ``"1e3"``; both surprise users of YAML 1.2 tools.
    """

    def construct_mapping(self, node: yaml.Node, deep: bool = False) -> dict[Any, Any]:
        if isinstance(node, yaml.MappingNode):
            self.flatten_mapping(node)
            seen: dict[Any, yaml.Node] = {}
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=True)
                try:
                    duplicate = key in seen
                except TypeError:  # an unhashable key: let the base class report it
                    break
                if duplicate:
                    first = seen[key].start_mark
                    raise yaml.constructor.ConstructorError(
                        None,
                        None,
                        f"duplicate key {key!r} (first at line {first.line + 1})",
                        key_node.start_mark,
                    )
                seen[key] = key_node
        return super().construct_mapping(node, deep=deep)  # type: ignore[arg-type]


StrictLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def read_text_file(path: str | Path, what: str, *, max_bytes: int = MAX_DOCUMENT_BYTES) -> str:
    """Read a regular UTF-8 text file of at most ``max_bytes``.

    ``what`` names the file in messages ("scenario file", "parameter file").

    Raises
    ------
    ConfigError
        If the file is missing, not a regular file, unreadable, too large or not UTF-8.
    """
    path = Path(path)
    try:
        st = path.stat()
    except OSError as exc:
        raise ConfigError(f"cannot read {what} {path}: {exc.strerror}") from None
    import stat

    if stat.S_ISDIR(st.st_mode):
        raise ConfigError(f"cannot read {what} {path}: it is a directory; give a YAML file")
    if not stat.S_ISREG(st.st_mode):
        raise ConfigError(f"cannot read {what} {path}: not a regular file")
    try:
        with path.open("rb") as fh:
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        raise ConfigError(f"cannot read {what} {path}: {exc.strerror}") from None
    if len(data) > max_bytes:
        raise ConfigError(
            f"{path}: {what} larger than {max_bytes // 1024} KiB; is it the right file?"
        )
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"{path}: {what} is not UTF-8 text (byte 0x{data[exc.start]:02x} at offset "
            f"{exc.start}); save it as UTF-8"
        ) from None
    if "\x00" in text:
        raise ConfigError(f"{path}: {what} is a binary file, not YAML text")
    return text.removeprefix("\ufeff")


def parse_yaml(text: str, source: str) -> Any:
    """Parse one YAML document with :class:`StrictLoader`; errors name ``source``."""
    try:
        return yaml.load(text, Loader=StrictLoader)  # a SafeLoader subclass
    except yaml.YAMLError as exc:
        raise ConfigError(f"{source}: not valid YAML: {yaml_error_message(exc)}") from None
    except (RecursionError, ValueError, OverflowError) as exc:
        detail = "nested too deeply" if isinstance(exc, RecursionError) else str(exc)
        raise ConfigError(f"{source}: not valid YAML: {detail}") from None


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in pairs:
        if k in out:
            raise ValueError(f"duplicate key {k!r}")
        out[k] = v
    return out


def load_document(path: str | Path, what: str) -> Any:
    """Read and parse a YAML (or, by suffix ``.json``, JSON) document strictly.

    Returns the parsed document (``None`` for an empty file).
    """
    path = Path(path)
    text = read_text_file(path, what)
    if path.suffix.lower() == ".json":
        try:
            return json.loads(text, object_pairs_hook=_no_duplicates)
        except (json.JSONDecodeError, ValueError, RecursionError) as exc:
            detail = "nested too deeply" if isinstance(exc, RecursionError) else str(exc)
            raise ConfigError(f"{path}: not valid JSON: {detail}") from None
    return parse_yaml(text, str(path))


# -- output directories as a unit ------------------------------------------------------

OUTPUT_NAMES = frozenset(
    {
        "summary.json",
        "trajectory.csv",
        "events.csv",
        "paths.png",
        "lean.png",
        "animation.gif",
        "balance.png",
        "results.csv",
        "results.parquet",
        "table.md",
        "success_vs_impulse.png",
        "time_to_goal.png",
    }
)
"""Files gracenav writes into an output directory; an existing ``--out`` holding
anything else is not replaced."""


def _glob_escape(name: str) -> str:
    """``name`` with glob metacharacters escaped."""
    import glob

    return glob.escape(name)


def _blocked_signals() -> Any:
    """A context in which SIGINT and SIGTERM wait until it ends (main thread only)."""
    import contextlib
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return contextlib.nullcontext()

    @contextlib.contextmanager
    def block() -> Any:
        sigs = {signal.SIGINT, signal.SIGTERM}
        old = signal.pthread_sigmask(signal.SIG_BLOCK, sigs)
        try:
            yield
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)

    return block()


def check_output_dir(path: str | Path, flag: str = "--out") -> Path:
    """Check that ``path`` can become an output directory, before any work is done.

    It must be absent, or a directory holding only files gracenav writes; its nearest
    existing ancestor must be a directory.

    Raises
    ------
    OutputError
        With a one-line message naming ``flag`` and the path.
    """
    from gracenav.errors import OutputError

    path = Path(path)
    try:
        here: Path | None = Path.cwd().resolve()
    except OSError:  # no current directory: nothing to protect
        here = None
    if here is not None and path.resolve() in (here, *here.parents):
        raise OutputError(
            f"{flag} {path} is the current directory or holds it; give a directory "
            "of its own, e.g. out/run1 (it is replaced as a whole)"
        )
    if path.exists() or path.is_symlink():
        if not path.is_dir():
            raise OutputError(f"{flag} {path} exists and is not a directory; give a directory")
        try:
            others = sorted(e.name for e in path.iterdir() if e.name not in OUTPUT_NAMES)
        except OSError as exc:
            raise OutputError(f"{flag} {path}: cannot list it: {exc.strerror}") from None
        if others:
            shown = ", ".join(others[:3]) + (", ..." if len(others) > 3 else "")
            raise OutputError(
                f"{flag} {path} holds files gracenav did not write ({shown}); give a new or "
                "empty directory (its content is replaced as a whole)"
            )
    for parent in path.absolute().parents:
        if parent.exists():
            if not parent.is_dir():
                raise OutputError(f"{flag} {path}: {parent} is a file, not a directory")
            break
        if parent.is_symlink():
            raise OutputError(f"{flag} {path}: {parent} is a broken symbolic link")
    return path


#: The signal (SIGINT or SIGTERM) the command line's handler received, if any. Python
#: ignores an exception raised while it runs some callbacks (an import lock's, a weak
#: reference's), so a signal can fail to stop the command; outputs are then still not
#: published (:meth:`OutputDir.__exit__`) and the command line reports the signal.
_pending_signal: int | None = None


def note_signal(signum: int | None) -> None:
    """Record (or, with None, clear) the signal that should stop the command."""
    global _pending_signal
    _pending_signal = signum


def pending_signal() -> int | None:
    """The signal recorded by :func:`note_signal`, if any."""
    return _pending_signal


class OutputDir:
    """An output directory written as a unit.

    On entry ``path`` is checked (:func:`check_output_dir`), a lock beside it is taken
    (a second run into the same ``path`` is refused) and a fresh staging directory is
    created beside it; write every file into :attr:`staging`. On a normal exit the
    staging directory replaces ``path`` (previous results are removed only then); on an
    exception, including KeyboardInterrupt, it is deleted and ``path`` is untouched.
    Leftovers of a run killed outright are cleaned up by the next run into ``path``.
    All of this happens before any heavy work, so an unusable ``path`` fails at once.

    Parameters
    ----------
    path : path-like
    flag : str
        How messages name the location (the CLI option).
    """

    def __init__(self, path: str | Path, flag: str = "--out") -> None:
        # Absolute and normalised ('a/../b'), so that the lock and the staging
        # directory are siblings of the directory itself.
        self.path = Path(os.path.abspath(check_output_dir(path, flag)))
        self.flag = flag
        self.staging = Path()
        self._lock_fd = -1
        self._lock_path = self.path.parent / f".{self.path.name}.lock"

    def _fail(self, what: str, exc: OSError) -> Exception:
        from gracenav.errors import OutputError

        return OutputError(f"{self.flag} {self.path}: cannot {what}: {exc.strerror}")

    def _lock(self) -> None:
        import fcntl

        from gracenav.errors import OutputError

        while True:
            try:
                fd = os.open(self._lock_path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise self._fail(f"write in {self.path.parent}", exc) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                raise OutputError(
                    f"{self.flag} {self.path} is in use by another gracenav run (lock "
                    f"{self._lock_path}); wait for it to finish or choose another directory"
                ) from None
            # The holder before us may have removed the file after we opened it: only a
            # lock on the file that is still there counts.
            try:
                same = os.stat(self._lock_path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                self._lock_fd = fd
                return
            os.close(fd)

    def _unlock(self) -> None:
        if self._lock_fd >= 0:
            try:
                os.unlink(self._lock_path)
            except OSError:
                pass
            os.close(self._lock_fd)
            self._lock_fd = -1

    def __enter__(self) -> OutputDir:
        from gracenav.errors import OutputError

        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise self._fail(f"create {self.path.parent}", exc) from None
        self._lock()
        try:
            self._recover()
            check_output_dir(self.path, self.flag)  # again, now that we hold the lock
            with _blocked_signals():  # no interrupt between creating and recording it
                self.staging = Path(
                    tempfile.mkdtemp(prefix=f".{self.path.name}.tmp-", dir=self.path.parent)
                )
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(self.staging, 0o777 & ~umask)
        except OutputError:
            self._cleanup()
            raise
        except OSError as exc:
            self._cleanup()
            raise self._fail(f"write in {self.path.parent}", exc) from None
        except BaseException:
            self._cleanup()
            raise
        return self

    def _cleanup(self) -> None:
        import shutil

        with _blocked_signals():  # a second Ctrl-C must not leave half a directory
            try:
                if self.staging != Path() and self.staging.exists():
                    shutil.rmtree(self.staging, ignore_errors=True)
            finally:
                self._unlock()

    def _recover(self) -> None:
        """Clean up after a run that was killed outright (SIGKILL, power loss): restore
        the previous results if it died between the two renames of :meth:`_publish`,
        and delete its staging directories. Called with the lock held, so no other run
        owns them."""
        import shutil

        parent, name = self.path.parent, self.path.name
        for old in sorted(parent.glob(f".{_glob_escape(name)}.old-*")):
            previous = old / "previous"
            if previous.is_dir() and not (self.path.exists() or self.path.is_symlink()):
                os.replace(previous, self.path)
            shutil.rmtree(old, ignore_errors=True)
        for tmp in parent.glob(f".{_glob_escape(name)}.tmp-*"):
            shutil.rmtree(tmp, ignore_errors=True)

    def _publish(self) -> None:
        import shutil

        old = None
        with _blocked_signals():
            if self.path.is_dir():
                old = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.old-", dir=self.path.parent))
                os.replace(self.path, old / "previous")
            try:
                os.replace(self.staging, self.path)
            except OSError:
                if old is not None:
                    os.replace(old / "previous", self.path)
                raise
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        try:
            if exc_type is None:
                if _pending_signal is not None:  # the signal's exception was swallowed
                    raise KeyboardInterrupt
                try:
                    self._publish()
                except OSError as err:
                    raise self._fail("replace it with the new results", err) from None
        finally:
            self._cleanup()
