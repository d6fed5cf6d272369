"""Spectral data files (QE, colour filters, IR cut): confined to resources/, read and validated once.

A spectrum CSV has a header row (wavelength column, then one name per curve) and rows of numbers:
wavelengths in nm, strictly increasing, then the curves. Curves are transmittances or quantum
efficiencies: finite and in [0, 1]. Every problem is an InputFileError naming the file and the
line or column; no message echoes the file's contents.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path, PurePosixPath

import numpy as np

from workbench.errors import InputFileError, InvalidValueError
from workbench.files import read_text
from workbench.resource_dir import RESOURCES

MAX_CURVES = 64
WAVELENGTH_RANGE_NM = (100.0, 3000.0)


@dataclass(frozen=True)
class SpectrumTable:
    """A validated spectrum file: wavelengths (nm, strictly increasing) and curves (N, K) in [0, 1]."""

    path: Path
    wavelengths_nm: np.ndarray
    values: np.ndarray
    names: tuple[str, ...]


def spectrum_path(name: str) -> Path:
    """The file of a spectrum named relative to resources/ ('sensors/ir_cut_650.csv'); ValueError
    for an absolute name or one with '..' (spectral data is confined to resources/ like lenses)."""
    rel = PurePosixPath(str(name).replace("\\", "/"))
    if not str(name) or rel.is_absolute() or ".." in rel.parts:
        raise InvalidValueError(f"spectral data file {name!r}: give a path relative to {RESOURCES} "
                         "(no '..', not absolute)")
    return RESOURCES / rel


def read_spectrum(name: str) -> SpectrumTable:
    """The validated table of a spectrum file (cached per file version)."""
    p = spectrum_path(name)
    try:
        st = os.stat(p)
    except OSError:
        raise InputFileError(p, "no such spectral data file") from None
    return _read(str(p), st.st_mtime_ns, st.st_size)


@lru_cache(maxsize=32)
def _read(path: str, _mtime_ns: int, _size: int) -> SpectrumTable:
    p = Path(path)
    lines = [(n, line) for n, line in enumerate(read_text(p, "spectrum CSV").splitlines(), 1) if line.strip()]
    if len(lines) < 3:
        raise InputFileError(p, "needs a header row and at least two rows of numbers")
    header = [c.strip() for c in lines[0][1].split(",")]
    names = tuple(header[1:])
    if not 1 <= len(names) <= MAX_CURVES or not all(names) or len(set(names)) != len(names):
        raise InputFileError(p, f"header row: a wavelength column, then 1–{MAX_CURVES} distinct, non-empty "
                                "curve names")
    rows = []
    for lineno, line in lines[1:]:
        cells = line.split(",")
        try:
            if len(cells) != len(header):
                raise ValueError
            rows.append([float(c) for c in cells])
        except ValueError:
            raise InputFileError(p, f"line {lineno}: expected {len(header)} comma-separated numbers") from None
    data = np.array(rows, dtype=np.float64)
    if not np.all(np.isfinite(data)):
        lineno = lines[1 + int(np.argwhere(~np.isfinite(data))[0, 0])][0]
        raise InputFileError(p, f"line {lineno}: every value must be a finite number")
    wl, values = data[:, 0], data[:, 1:]
    lo, hi = WAVELENGTH_RANGE_NM
    if wl[0] < lo or wl[-1] > hi:
        raise InputFileError(p, f"wavelengths must lie in {lo:g}–{hi:g} nm")
    steps = np.diff(wl)
    if np.any(steps <= 0):
        lineno = lines[2 + int(np.argmax(steps <= 0))][0]
        raise InputFileError(p, f"line {lineno}: wavelengths must increase strictly from row to row "
                                "(no descending, shuffled or repeated wavelengths)")
    bad = np.argwhere((values < 0) | (values > 1))
    if bad.size:
        row, col = bad[0]
        raise InputFileError(p, f"line {lines[1 + row][0]}, curve {names[col]!r}: transmittance / QE "
                                "must lie in [0, 1]")
    wl.setflags(write=False)
    values = np.ascontiguousarray(values)
    values.setflags(write=False)
    return SpectrumTable(p, wl, values, names)


def check_spectrum_file(name: str) -> str:
    """Validate a spectral data file name for a parameter (ValueError/InputFileError); return it."""
    read_spectrum(name)
    return name


def resample(table: SpectrumTable, wavelengths_nm: np.ndarray) -> np.ndarray:
    """The curves at `wavelengths_nm` (linear interpolation), shape (Nλ, K); zero outside the
    table's range: a filter or QE curve the file does not describe is taken to pass nothing."""
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    out = np.stack([np.interp(wl, table.wavelengths_nm, table.values[:, k])
                    for k in range(table.values.shape[1])], axis=-1)
    out[(wl < table.wavelengths_nm[0]) | (wl > table.wavelengths_nm[-1])] = 0.0
    return out
