"""Zero-phase low-pass, derivatives and decimation for identification (IDIM practice: parallel
filtering).

The identification model sigma = Y(q, qd, qdd) pi holds at every sample; qd and qdd are not
measured. derivatives() gives the low-passed pose and its first two derivatives, lowpass() the
same low-pass for any other signal: applied to the regressor's columns and to the measured
forces alike, lowpass(Y) pi = lowpass(sigma) stays exact (the filter is linear and the same),
while the noise above the cut-off leaves both sides.

Everything is done in the frequency domain, on one FFT of the record (extended, see below):
the low-pass multiplies the spectrum by a real window H(f), 1 up to the cut-off f_c, 0 from
(1 + TAPER) f_c, between them a step smooth to every order (_window); a derivative multiplies
it by (i 2 pi f)^k. A real window is zero-phase by construction, and on a band-limited periodic
record (a Fourier series over whole periods, harmonics below f_c) nothing is approximated: the
pose and its derivatives come back to round-off (tests: below 1e-14 of their peak).

The FFT sees the record as one period of a periodic signal, so the record is extended first
(Filter.extension), chosen by choose_filter from the pose, once for all signals of the run:

- "periodic": the record is whole periods (its last sample one period before the first);
- "closed": whole periods and the last sample repeats the first (t = 0 .. T inclusive): the
  last sample is left out, then given the first one's value;
- "reflect": any other record: the line through its end samples taken off, the rest mirrored
  about its end with a sign change (odd extension, length 2N - 2), the line put back after
  (a line passes the low-pass unchanged; its derivative is its slope). The extension is
  continuous with its first derivative; the second derivative changes sign at the seam, a jump
  whose ringing the smooth window keeps within a few periods of f_c. decimated() drops
  Filter.trim = TRIM_PERIODS periods of f_c at each end; inside, a smooth record's qdd is
  within ~1e-5 of its peak, qd and the pose within that integrated over 1 / f_c (at a cut-off
  of 4 Hz: 2e-6 and 1.2e-7 of their peaks; tests), not round-off.

The extension is the first of EXTENSIONS whose spectrum has at most SEAM_FACTOR times the least
energy in the top half of the band (above rate / 4, where an identification run has no motion):
the right one adds nothing there, a wrong one adds the broadband content of a jump or a kink at
the seam; with noise, which is the same in all, "periodic" keeps its place.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stewart_fmu.errors import StewartError

EXTENSIONS = ("periodic", "closed", "reflect")
TAPER = 1.0            # the window falls from 1 at f_c to 0 at (1 + TAPER) f_c (_window)
MARGIN = 1.2           # default cut-off: this times the highest frequency the pose holds
REL_FLOOR = 1e-10      # a spectral line counts when above this times its axis's largest one ...
NOISE_FACTOR = 10.0    # ... and above this times the largest line above rate / 4 (the noise)
MAX_CUTOFF = 0.2       # the cut-off at most this times the rate (the decimation keeps >= 5x)
DECIMATED_RATIO = 5.0  # default decimation: the decimated rate stays >= this times f_c
SEAM_FACTOR = 2.0      # an extension is taken over an earlier one when this much quieter
TRIM_PERIODS = 8.0     # "reflect": periods of f_c dropped at each end by decimated() (at most
                       # a quarter of the record each)
_BLOCK = 64            # columns per FFT in lowpass (bounds the memory of long regressors)


@dataclass(frozen=True)
class Filter:
    """The low-pass of a run's signals: cut-off (Hz, the pass band's edge), sampling rate (Hz),
    decimation factor, the record's extension (EXTENSIONS) and the samples decimated() drops at
    each end."""

    cutoff: float
    rate: float
    decimate: int
    extension: str = "reflect"
    trim: int = 0


def choose_filter(t: np.ndarray, q: np.ndarray, cutoff: float | None = None,
                  decimate: int | None = None) -> Filter:
    """The filter for a run sampled at times t (uniform) with poses q (N, 6).

    Default cut-off: MARGIN times the highest frequency at which any pose axis still has a
    spectral line above both REL_FLOOR of its largest line and NOISE_FACTOR times its largest
    line above rate / 4 (the noise floor: the largest line, not a mean, as noise is coloured,
    an encoder's quantization of a slow motion loudest at low frequencies), within [20
    frequency bins, MAX_CUTOFF rate]: the excitation's last harmonic passes untouched, the
    noise above it does not. Default decimation: the largest factor keeping the decimated
    rate >= DECIMATED_RATIO f_c. The extension and the trim follow from the pose (module
    doc): build a Filter here, not by hand."""
    t, q = np.asarray(t, dtype=float), np.asarray(q, dtype=float)
    n = len(t)
    rate = (n - 1) / (t[-1] - t[0])
    extension = _extension(q)
    if cutoff is None:
        cutoff = _default_cutoff(q, rate, extension)
    elif not (np.isfinite(cutoff) and 0 < cutoff < rate / 2):
        raise StewartError(f"filter cut-off must be above 0 and below half the sampling rate "
                           f"({rate / 2:.6g} Hz), got {cutoff!r} Hz")
    if decimate is None:
        decimate = max(1, int(np.floor(rate / (DECIMATED_RATIO * cutoff))))
    elif isinstance(decimate, bool) or int(decimate) != decimate or decimate < 1:
        raise StewartError(f"decimation must be a whole number >= 1, got {decimate!r}")
    trim = min(int(np.ceil(TRIM_PERIODS * rate / cutoff)), n // 4) if extension == "reflect" \
        else 0
    return Filter(float(cutoff), float(rate), int(decimate), extension, trim)


def derivatives(q: np.ndarray, f: Filter, shift: float = 0.0
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The zero-phase low-passed q (N, ...) and its first two time derivatives; with `shift`
    (s), those of q(t + shift) at the same times (a band-limited time shift: the spectrum times
    exp(i 2 pi f shift), exact on a periodic record)."""
    q_f, qd, qdd = _apply(q, f, (0, 1, 2), shift)
    return q_f, qd, qdd


def lowpass(x: np.ndarray, f: Filter) -> np.ndarray:
    """The same zero-phase low-pass as derivatives()'s, on any (N, ...) array (per column)."""
    return _apply(x, f, (0,))[0]


def decimated(x: np.ndarray, f: Filter) -> np.ndarray:
    """Every f.decimate-th sample of x (N, ...), f.trim samples dropped at each end (the reach
    of the seam of a reflected record, none for a periodic one)."""
    return x[f.trim:len(x) - f.trim:f.decimate]


def white_noise_factor(f: Filter) -> float:
    """How much more variance white noise has in the pass band after lowpass + decimated than
    least squares assumes of the decimated samples: (rate / 2 / decimate) / integral of H(f)^2
    over [0, rate / 2]. Least squares takes the decimated noise as white over the decimated
    band, but the window passes less than that band (H = 0 above (1 + TAPER) f_c), so the
    samples are correlated and its covariance is low by this factor; 1 when the window fills
    the decimated band."""
    freq = np.linspace(0.0, f.rate / 2, 200_001)
    h2 = _window(freq, f.cutoff) ** 2
    band = float(np.sum((h2[1:] + h2[:-1]) / 2) * (freq[1] - freq[0]))
    return max(1.0, f.rate / 2 / f.decimate / band)


def _apply(x: np.ndarray, f: Filter, orders: tuple[int, ...], shift: float = 0.0
           ) -> list[np.ndarray]:
    """The low-passed k-th derivatives (k in orders) of x(t + shift) along its first axis."""
    x = np.asarray(x, dtype=float)
    n, shape = x.shape[0], x.shape[1:]
    flat = x.reshape(n, -1)
    outs = [np.empty_like(flat) for _ in orders]
    closed, odd = f.extension == "closed", f.extension == "reflect"
    m = n - 1 if closed else n                       # the samples of one period
    size = 2 * m - 2 if odd else m
    freq = np.fft.rfftfreq(size, 1.0 / f.rate)
    gains = [_window(freq, f.cutoff) * (2j * np.pi * freq) ** k
             * np.exp(2j * np.pi * freq * shift) for k in orders]
    ramp = np.linspace(0.0, 1.0, n)[:, None] + shift * f.rate / (n - 1)
    for c in range(0, flat.shape[1], _BLOCK):
        block = flat[:m, c:c + _BLOCK]
        if odd:       # the line through both ends off, then mirrored with a sign change
            rise = block[-1] - block[0]
            block = block - block[0] - ramp * rise
            block = np.concatenate([block, -block[-2:0:-1]])
        spectrum = np.fft.rfft(block, axis=0)
        for k, out, gain in zip(orders, outs, gains):
            out[:m, c:c + _BLOCK] = np.fft.irfft(spectrum * gain[:, None], n=size, axis=0)[:m]
            if odd and k == 0:                       # the line back (a line passes the filter)
                out[:, c:c + _BLOCK] += flat[0, c:c + _BLOCK] + ramp * rise
            elif odd and k == 1:
                out[:, c:c + _BLOCK] += rise * f.rate / (n - 1)
    if closed:
        for out in outs:
            out[-1] = out[0]
    return [out.reshape((n, *shape)) for out in outs]


def _window(freq: np.ndarray, cutoff: float) -> np.ndarray:
    """1 up to the cut-off, 0 from (1 + TAPER) cutoff, between them the smooth step
    g(1 - s) / (g(s) + g(1 - s)), g(s) = exp(-1/s): smooth to every order, so that the filter's
    impulse response decays faster than any power of time (the seam of a reflected record
    reaches only a few periods of the cut-off into it)."""
    s = np.clip((freq - cutoff) / (TAPER * cutoff), 0.0, 1.0)
    with np.errstate(divide="ignore", over="ignore"):
        g0, g1 = np.exp(-1.0 / s), np.exp(-1.0 / (1.0 - s))
    return g1 / (g0 + g1)


def _extended(q: np.ndarray, extension: str) -> np.ndarray:
    """One period of the record as the FFT sees it under `extension`."""
    if extension == "closed":
        return q[:-1]
    if extension == "reflect":
        y = q - q[0] - np.linspace(0.0, 1.0, len(q))[:, None] * (q[-1] - q[0])
        return np.concatenate([y, -y[-2:0:-1]])
    return q


def _extension(q: np.ndarray) -> str:
    """The extension whose spectrum has the least energy per sample above rate / 4 (summed over
    the axes, each scaled by its own spread); ties go to the first of EXTENSIONS."""
    span = np.ptp(q, axis=0)
    scale = np.where(span > 0, span, 1.0)
    top = []
    for ext in EXTENSIONS:
        x = _extended(q, ext) / scale
        x = x - x.mean(axis=0)
        spectrum = np.abs(np.fft.rfft(x, axis=0)) ** 2
        top.append(spectrum[len(spectrum) // 2:].sum() / len(x) ** 2)
    return next(e for e, v in zip(EXTENSIONS, top) if v <= SEAM_FACTOR * min(top))


def _default_cutoff(q: np.ndarray, rate: float, extension: str) -> float:
    """MARGIN times the highest frequency with a pose line above the floor (choose_filter)."""
    x = _extended(q, extension)
    x = x - x.mean(axis=0)
    amp = np.abs(np.fft.rfft(x, axis=0))[1:]         # no DC
    freq = np.fft.rfftfreq(len(x), 1.0 / rate)[1:]
    top = freq > rate / 4
    highest = 0.0
    for c in range(amp.shape[1]):
        a = amp[:, c]
        if a.max() == 0.0:
            continue                                 # an axis that does not move
        floor = max(REL_FLOOR * a.max(), NOISE_FACTOR * float(a[top].max()))
        above = np.flatnonzero(a > floor)
        if above.size:
            highest = max(highest, float(freq[above[-1]]))
    bin_width = rate / len(x)
    return float(np.clip(MARGIN * highest, 20 * bin_width, MAX_CUTOFF * rate))
