"""A catalogue of drives to choose from (`size --catalogue drives.csv`): one row per drive, a
motor with its gearbox and pinion, the columns (header row first, any order, SI units):

    name               text, unique, non-empty, at most 64 characters, printable; not
                       starting with = + - @ (a spreadsheet opening a result's CSV would
                       run it as a formula)
    gear_ratio         1       gearbox reduction zeta (motor turns per pinion turn)
    pinion_radius      m       pitch radius r of the rack-and-pinion
    rotor_inertia      kg m^2  at the motor shaft: rotor plus the gearbox's input side
    peak_torque        N m     at the motor shaft, the most it gives for a short time
    continuous_torque  N m     at the motor shaft, the most it gives for good (thermal, S1);
                               at most peak_torque
    max_speed          rad/s   the motor's highest speed (rpm x 2 pi / 60)
    price              any currency, the same for every row   } at least one of the two;
    mass               kg                                      } ranked by price, else mass

The three drive keys keep the bounds of the scene's [drive] table (stewart_fmu.table, the
FMU's parameter bounds); the others are bounded in LIMITS. A bad file raises CatalogueError
naming the file, the line and the column.
"""
from __future__ import annotations

import csv
import io as textio
import math
from dataclasses import dataclass
from pathlib import Path

from stewart_fmu.budget import read_input
from stewart_fmu.errors import StewartError
from stewart_fmu.table import bound_reason, scene_groups

CATALOGUE_BYTES = 1024**2    # a catalogue is a short table
MAX_DRIVES = 10_000          # rows: each is one task of the catalogue sweep
DRIVE_KEYS = ("gear_ratio", "pinion_radius", "rotor_inertia")
COST_KEYS = ("price", "mass")
# column -> (lowest, open at the low end, highest, unit): the physical bounds of the ratings
# (the lowest: a thousandth of the smallest such motor's, 1 mN m and 1 rad/s) and of a catalogue
# drive's gearbox beyond the scene's [drive] bound (gear_ratio > 0): a gearbox speeding the
# pinion up more than 100 times drives no rack (the torque it would ask is the rack force
# times the pinion radius over the ratio)
LIMITS = {"peak_torque": (1e-6, False, 1e5, "N m"),
          "continuous_torque": (1e-6, False, 1e5, "N m"),
          "max_speed": (1e-3, False, 2e4, "rad/s"),      # 2e4 rad/s: about 190,000 rpm
          "price": (0.0, False, 1e12, ""),
          "mass": (0.0, True, 1e5, "kg"),
          "gear_ratio": (1e-2, False, 1e5, "")}
MAX_NAME = 64
FORMULA_STARTS = "=+-@"   # OWASP's CSV injection list; tab and CR are stripped or not printable
REQUIRED = ("name", *DRIVE_KEYS, "peak_torque", "continuous_torque", "max_speed")
COLUMNS = (*REQUIRED, *COST_KEYS)


class CatalogueError(StewartError, ValueError):
    """A drive catalogue that cannot be read or holds a value outside its bounds."""


@dataclass(frozen=True)
class Drive:
    """One catalogue row (units in the module doc); price or mass None when not given."""

    name: str
    gear_ratio: float
    pinion_radius: float
    rotor_inertia: float
    peak_torque: float
    continuous_torque: float
    max_speed: float
    price: float | None = None
    mass: float | None = None

    @property
    def drive_table(self) -> dict[str, float]:
        """The scene's [drive] table this drive puts in place."""
        return {k: getattr(self, k) for k in DRIVE_KEYS}

    @property
    def cost(self) -> float:
        """What the ranking orders by: the price, else the mass."""
        return self.price if self.price is not None else self.mass


def read_catalogue(path: str | Path) -> tuple[Drive, ...]:
    """Every row of the catalogue, checked (CatalogueError: file, line, column, reason)."""
    path = Path(path)
    try:
        text = read_input(path, CATALOGUE_BYTES).decode("utf-8-sig")   # a spreadsheet's BOM
    except UnicodeDecodeError as exc:
        raise CatalogueError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    rows = _rows(path, text)
    if not rows:
        raise CatalogueError(f"{path}: empty, need a header row ({','.join(COLUMNS)})")
    header = [c.strip() for c in rows[0][1]]
    _check_header(path, rows[0][0], header)
    if len(rows) < 2:
        raise CatalogueError(f"{path}: no drives, only the header")
    if len(rows) - 1 > MAX_DRIVES:
        raise CatalogueError(f"{path}: {len(rows) - 1} drives, at most {MAX_DRIVES}")
    drives, names = [], {}
    for line, row in rows[1:]:
        drive = _drive(path, line, header, row)
        if drive.name in names:
            raise CatalogueError(f"{path}: line {line}, column 'name': {drive.name!r} already "
                                 f"on line {names[drive.name]}")
        names[drive.name] = line
        drives.append(drive)
    return tuple(drives)


def _check_header(path: Path, line: int, header: list[str]) -> None:
    for column in header:
        if column not in COLUMNS:
            raise CatalogueError(f"{path}: line {line}: unknown column {column!r} (columns: "
                                 f"{', '.join(COLUMNS)})")
        if header.count(column) > 1:
            raise CatalogueError(f"{path}: line {line}: column {column!r} given twice")
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        plural = "s" if len(missing) > 1 else ""
        raise CatalogueError(f"{path}: line {line}: missing column{plural} "
                             f"{', '.join(missing)}")
    if not any(c in header for c in COST_KEYS):
        raise CatalogueError(f"{path}: line {line}: need a price or a mass column to rank the "
                             "drives")


def _rows(path: Path, text: str) -> list[tuple[int, list[str]]]:
    """(file line, cells) of every row that is not blank (a quoted cell over several lines
    counts from its first line)."""
    reader = csv.reader(textio.StringIO(text, newline=""))
    rows, line = [], 1
    try:
        for row in reader:      # bounded: the text is at most CATALOGUE_BYTES
            if any(cell.strip() for cell in row):
                rows.append((line, row))
            line = reader.line_num + 1
    except csv.Error as exc:
        raise CatalogueError(f"{path}: line {line}: not CSV ({exc})") from None
    return rows


def _drive(path: Path, line: int, header: list[str], row: list[str]) -> Drive:
    if len(row) != len(header):
        raise CatalogueError(f"{path}: line {line}: {len(row)} cells for {len(header)} columns")
    cells = {c: v.strip() for c, v in zip(header, row)}
    name = cells["name"]
    why = _name_reason(name)
    if why is not None:
        raise CatalogueError(f"{path}: line {line}, column 'name': {why}")
    values: dict[str, float | str] = {"name": name}
    for column in header:
        if column != "name":
            values[column] = _number(path, line, column, cells[column])
    if values["continuous_torque"] > values["peak_torque"]:
        raise CatalogueError(f"{path}: line {line}, column 'continuous_torque': "
                             f"{values['continuous_torque']!r} N m above peak_torque "
                             f"{values['peak_torque']!r} N m")
    return Drive(**values)


def _name_reason(name: str) -> str | None:
    """Why a drive's name cannot be written into a result (None: it can)."""
    if not name:
        return "empty"
    if len(name) > MAX_NAME:
        return f"{len(name)} characters, at most {MAX_NAME}"
    if not name.isprintable():
        return f"{name!r} holds a control character"
    if name[0] in FORMULA_STARTS:
        return (f"{name!r} starts with {name[0]!r}, which a spreadsheet opening the results "
                "would read as a formula")
    return None


def _number(path: Path, line: int, column: str, text: str) -> float:
    where = f"{path}: line {line}, column '{column}'"
    try:
        value = float(text)
    except ValueError:
        raise CatalogueError(f"{where}: not a number: {text!r}") from None
    if not math.isfinite(value):
        raise CatalogueError(f"{where}: not finite: {text!r}")
    reason = None
    if column in DRIVE_KEYS:
        reason = bound_reason(scene_groups()[f"drive.{column}"], value)
    if reason is None and column in LIMITS:
        low, open_low, high, unit = LIMITS[column]
        unit = f" {unit}" if unit else ""
        if value < low or (open_low and value == low):
            reason = f"must be {'>' if open_low else '>='} {low:g}, got {value!r}"
        elif value > high:
            reason = f"must be <= {high:g}{unit}, got {value!r}"
    if reason is not None:
        raise CatalogueError(f"{where}: {reason}")
    return value
