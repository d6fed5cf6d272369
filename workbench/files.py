"""Reading user files safely and writing files atomically.

Readers turn every way a file can be unusable (a folder, no permission, too large, not UTF-8, bad
JSON, JSON nested too deeply, a key given twice) into an InputFileError naming the file; no message
echoes the file's contents. `atomic_write_text` writes through a symbolic link to its target, keeps
the target's permission bits, and never leaves a half-written file or a stale temporary behind.

Every JSON file or line the workbench writes goes through `json_text`: strict JSON (no NaN or
Infinity, which are not JSON), numpy numbers as plain numbers; an infinite or undefined quantity
is written as null by its measurement, with a field that says why (e.g. "unbounded (noise off)").
"""
from __future__ import annotations

import json
import math
import os
import secrets
import stat
from pathlib import Path

from workbench.errors import InputFileError, OutputPathError

MAX_INPUT_BYTES = 16 * 2 ** 20
"""Largest project, lens or spectrum file read (16 MiB); the real ones are a few kB."""


def read_bytes(path: str | os.PathLike, what: str, max_bytes: int = MAX_INPUT_BYTES) -> bytes:
    """The bytes of a regular file; InputFileError (naming the file) if it cannot be read."""
    p = Path(path)
    try:
        st = os.stat(p)
        if stat.S_ISDIR(st.st_mode):
            raise InputFileError(p, f"is a folder, not a {what}")
        if not stat.S_ISREG(st.st_mode):
            raise InputFileError(p, f"is not a regular file (a {what} is a file on disk)")
        if st.st_size > max_bytes:
            raise InputFileError(p, f"is {st.st_size:,} bytes; a {what} is at most {max_bytes:,} bytes")
        with open(p, "rb") as fh:
            raw = fh.read(max_bytes + 1)
    except FileNotFoundError:
        raise InputFileError(p, "no such file") from None
    except PermissionError:
        raise InputFileError(p, "no permission to read it") from None
    except NotADirectoryError:
        raise InputFileError(p, "a folder in the path is a file") from None
    except OSError as exc:
        raise InputFileError(p, f"cannot be read ({exc.strerror or type(exc).__name__})") from None
    if len(raw) > max_bytes:
        raise InputFileError(p, f"a {what} is at most {max_bytes:,} bytes")
    return raw


def decode_text(raw: bytes, path: str | os.PathLike, what: str) -> str:
    """UTF-8 text (a UTF-8 or UTF-16 byte-order mark is honoured); InputFileError if it is not text."""
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        encoding = "utf-16"
    else:
        encoding = "utf-8-sig"
    try:
        text = raw.decode(encoding)
    except UnicodeDecodeError as exc:
        raise InputFileError(path, f"is not UTF-8 text (a {what} is a text file; undecodable byte at "
                                   f"offset {exc.start})") from None
    if "\x00" in text:
        raise InputFileError(path, f"holds NUL characters: a binary file, not a {what}")
    return text


def read_text(path: str | os.PathLike, what: str, max_bytes: int = MAX_INPUT_BYTES) -> str:
    """The text of a file (see read_bytes, decode_text)."""
    return decode_text(read_bytes(path, what, max_bytes), path, what)


class _DuplicateKey(Exception):
    def __init__(self, key: str):
        self.key = key


def _refuse_duplicate_keys(pairs: list[tuple[str, object]]) -> dict:
    out: dict = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


def parse_json(text: str, path: str | os.PathLike, what: str) -> object:
    """Decode JSON text; a syntax error, nesting too deep or a key given twice is an InputFileError."""
    try:
        data = json.loads(text, object_pairs_hook=_refuse_duplicate_keys)
    except json.JSONDecodeError as exc:
        raise InputFileError(path, f"not valid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg} "
                                   f"(a {what} is JSON)") from None
    except RecursionError:
        raise InputFileError(path, f"JSON nested too deeply to be a {what}") from None
    except ValueError as exc:            # json refuses an integer of more digits than int() converts (4,300)
        raise InputFileError(path, f"not a usable {what}: {str(exc).split(';')[0]}; write the number with fewer "
                                   "digits") from None
    except _DuplicateKey as exc:
        key = exc.key if len(exc.key) <= 40 else exc.key[:37] + "..."
        raise InputFileError(path, f"a JSON object gives the key {key!r} twice; keep one") from None
    if not _valid_unicode(data):
        raise InputFileError(path, "a JSON string holds an unpaired surrogate escape (\\ud800–\\udfff): not "
                                   "valid Unicode")
    return data


def _valid_unicode(data: object) -> bool:
    """No string (key or value) holds an unpaired surrogate, which JSON's \\u escapes can spell."""
    stack = [data]
    while stack:
        node = stack.pop()
        if isinstance(node, dict):
            stack.extend(node.keys())
            stack.extend(node.values())
        elif isinstance(node, list):
            stack.extend(node)
        elif isinstance(node, str):
            try:
                node.encode("utf-8")
            except UnicodeEncodeError:
                return False
    return True


# ---------------------------------------------------------------- strict JSON
def _plain(obj):
    """numpy scalars and arrays, and paths, as JSON values; anything else is a bug."""
    if hasattr(obj, "tolist"):                   # numpy scalar or array
        return obj.tolist()
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(f"JSON output: cannot write a {type(obj).__name__}")


def non_finite_place(obj, where: str = "") -> str | None:
    """The dotted place of the first NaN or ±Infinity in a JSON-ready value, or None."""
    stack = [(where, obj)]
    while stack:
        place, node = stack.pop()
        if isinstance(node, dict):
            stack.extend((f"{place}.{k}" if place else str(k), v) for k, v in node.items())
        elif isinstance(node, (list, tuple)):
            stack.extend((f"{place}[{i}]", v) for i, v in enumerate(node))
        elif isinstance(node, float) or hasattr(node, "dtype"):
            try:
                values = node.tolist() if hasattr(node, "tolist") else node
            except (TypeError, ValueError):
                continue
            if isinstance(values, list):
                stack.append((place, values))
            elif isinstance(values, float) and not math.isfinite(values):
                return place or "(the value)"
    return None


def json_text(obj, indent: int | None = 1, default=_plain, **kwargs) -> str:
    """Strict JSON text of `obj` (allow_nan=False; numpy values as numbers). A NaN or ±Infinity is
    a bug of the code that made `obj` (it should write null and say why): ValueError naming where."""
    try:
        return json.dumps(obj, indent=indent, allow_nan=False, default=default, **kwargs)
    except ValueError:
        place = non_finite_place(obj)
        if place is None:
            raise
        raise ValueError(f"JSON output: {place} is not a finite number (NaN or Infinity are not JSON; "
                         "write null and say why)") from None


# ---------------------------------------------------------------- atomic write
_TMP_SUFFIX = ".tmp"


def _temp_name(target_name: str) -> str:
    return f".{target_name}.{os.getpid()}.{secrets.token_hex(4)}{_TMP_SUFFIX}"


def pid_alive(pid: int) -> bool:
    """Whether a process with this id exists (one we may not signal counts as alive)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale_temporaries(folder: Path, target_name: str) -> list[Path]:
    """Remove our temporaries of `target_name` (`.NAME.PID.HEX.tmp`) whose writer process is gone."""
    prefix = f".{target_name}."
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        name = entry.name
        if not (name.startswith(prefix) and name.endswith(_TMP_SUFFIX)):
            continue
        middle = name[len(prefix):-len(_TMP_SUFFIX)].split(".")
        if len(middle) != 2 or not middle[0].isdigit() or len(middle[1]) != 8:
            continue
        pid = int(middle[0])
        if pid == os.getpid() or pid_alive(pid):
            continue
        try:
            os.unlink(entry.path)
            removed.append(Path(entry.path))
        except OSError:
            pass
    return removed


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write text (UTF-8) to path atomically (atomic_write_bytes) and return the file written."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write bytes to path whole or not at all and return the file written.

    A symbolic link is written through (its target is replaced, the link stays); an existing file
    keeps its permission bits (and owner where allowed); a new file gets 0666 less the umask. The
    data go to a temporary file in the same folder, is flushed to disk and renamed over the
    target; temporaries that a killed writer left behind are removed on the next save."""
    return atomic_write_files({path: data})[0]


def atomic_write_files(files: dict) -> list[Path]:
    """Write several files (path → bytes) so that none changes unless all could be written: each
    goes to a temporary file first (as atomic_write_bytes); only when every one is on disk are
    they renamed over their targets, in the order given (e.g. an image before the record that
    describes it). A failure before that (a full disk) removes the temporaries and names the file."""
    staged = []
    try:
        for path, data in files.items():
            staged.append(_stage(path, data))
        for given, tmp, target in staged:
            try:
                os.replace(tmp, target)
            except OSError as exc:
                raise OutputPathError(given, f"cannot be written ({exc.strerror or exc})") from None
    except BaseException:
        for _, tmp, _ in staged:
            try:
                os.unlink(tmp)
            except OSError:
                pass
        raise
    for folder in {target.parent for _, _, target in staged}:
        _fsync_folder(folder)
    return [target for _, _, target in staged]


def _stage(path: str | os.PathLike, data: bytes) -> tuple[Path, Path, Path]:
    """(given path, its temporary file written and flushed, the target it will replace)."""
    given = Path(path)
    target = Path(os.path.realpath(given))
    folder = target.parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OutputPathError(given, "a folder in the path is a file") from None
    except OSError as exc:
        raise OutputPathError(given, f"cannot create its folder ({exc.strerror})") from None
    try:
        st = os.stat(target)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise OutputPathError(given, f"cannot be written ({exc.strerror})") from None
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise OutputPathError(given, "is a folder; give a file name")
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise OutputPathError(given, "exists and is not a regular file")
    remove_stale_temporaries(folder, target.name)
    tmp = folder / _temp_name(target.name)
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o666)
    except OSError as exc:
        raise OutputPathError(given, f"cannot write in {folder} ({exc.strerror})") from None
    try:
        try:
            if st is not None:
                try:
                    os.fchown(fd, st.st_uid, st.st_gid)
                except OSError:
                    pass
                os.fchmod(fd, stat.S_IMODE(st.st_mode))
            _write_all(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError) and not isinstance(exc, OutputPathError):
            raise OutputPathError(given, f"cannot be written ({exc.strerror or exc})") from None
        raise
    return given, tmp, target


def _fsync_folder(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def prepare_output_folder(path: str | os.PathLike) -> Path:
    """Create the output folder `path` (and its parents) and check that files can be written in it;
    OutputPathError if it is empty (which would mean the current folder), an existing file (or
    /dev/null), lies below a file, or is read-only."""
    if not str(path).strip():
        raise OutputPathError(path, "an empty output folder name; name a folder (e.g. --out out/)")
    p = Path(path)
    if os.path.lexists(p) and not p.is_dir():
        raise OutputPathError(p, "exists and is not a folder; give a folder for the outputs")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OutputPathError(p, "a folder in the path is a file") from None
    except OSError as exc:
        raise OutputPathError(p, f"cannot create the folder ({exc.strerror})") from None
    probe = p / _temp_name("write-check")
    try:
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        os.unlink(probe)
    except OSError as exc:
        raise OutputPathError(p, f"cannot write in the folder ({exc.strerror})") from None
    return p
