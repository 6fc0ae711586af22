"""How long a run may be: the tables a command holds must fit a stated memory budget.

A run keeps every sample of its tables in memory (the reference, the recorder's columns, the
result table) and writes them at the end: about SAMPLE_BYTES per sample in all (run.csv has
~55 float64 columns, the reference and the recorder as many again). MEMORY_BUDGET / SAMPLE_BYTES
samples is the limit; a longer --duration or --horizon is refused before any work starts
(numpy would otherwise fail half-way with "Unable to allocate ... TiB")."""
from __future__ import annotations

from stewart_fmu.budget import MEMORY_BUDGET, BudgetError, check_count
from stewart_fmu.errors import StewartError

SAMPLE_BYTES = 1024             # bytes per sample over every table a run holds
MAX_SAMPLES = MEMORY_BUDGET // SAMPLE_BYTES   # 2,097,152: 35 min at 1 kHz


def check_samples(option: str, seconds: float, rate: float, why: str = "") -> None:
    """Refuse `option` = `seconds` when its samples at `rate` exceed MAX_SAMPLES."""
    samples = seconds * rate
    try:
        check_count(f"{option} {seconds:g} s: samples", samples, SAMPLE_BYTES)
    except BudgetError:   # the one check; the line says what a run holds and what fits
        longest = MAX_SAMPLES / rate
        raise StewartError(
            f"{option} {seconds:g} s is {samples:.3g} samples at {rate:g} Hz"
            + (f" ({why})" if why else "")
            + f": at most {MAX_SAMPLES:,} fit the memory budget of "
            f"{MEMORY_BUDGET / 1024**3:g} GiB (about {SAMPLE_BYTES} bytes a sample over the "
            f"tables a run holds); use {option} {longest:.6g} or less") from None
