"""Families of shapes: near variants of a library shape (the paper's Section IV-C sweeps),
and the ``--vary`` settings that describe them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from rockscan.core._threads import one_blas_thread
from rockscan.core.errors import ParameterError, SpecError
from rockscan.core.library import ShapeSpec, sanitize_name
from rockscan.core.superformula import SuperformulaParams, round_significant, shape_radii

__all__ = ["MAX_VARIANTS", "VARY_NAMES", "family", "parse_vary", "sanitize_name"]


#: Names ``--vary`` accepts, and the parameters each one sets.
VARY_NAMES: dict[str, tuple[str, ...]] = {
    "m1": ("m1",),
    "m2": ("m2",),
    "n1": ("n1",),
    "n2": ("n2",),
    "n3": ("n3",),
    "a": ("a",),
    "b": ("b",),
    "m": ("m1", "m2"),
    "n23": ("n2", "n3"),
    "n": ("n1", "n2", "n3"),
}


#: Most variants one family may hold.
MAX_VARIANTS = 1000


_VARY_SYNTAX = "NAME=START:STOP:COUNT or NAME=V1,V2,..., e.g. n1=0.8:1.2:5"


def parse_vary(text: str) -> tuple[str, tuple[float, ...]]:
    """Parse one ``--vary`` setting.

    Parameters
    ----------
    text : str
        ``NAME=START:STOP:COUNT`` (COUNT values evenly spaced from START to STOP)
        or ``NAME=V1,V2,...``. NAME is a parameter (m1, m2, n1, n2, n3, a, b) or
        a group set together: ``m`` (m1 = m2), ``n23`` (n2 = n3, the paper's
        Fig. 16) or ``n`` (n1, n2 and n3).

    Returns
    -------
    name : str
    values : tuple of float

    Raises
    ------
    ParameterError
        With the expected syntax, on anything else.

    Examples
    --------
    >>> parse_vary("n1=0.8:1.2:5")
    ('n1', (0.8, 0.9, 1.0, 1.1, 1.2))
    >>> parse_vary("m=4,6")
    ('m', (4.0, 6.0))
    """
    name, sep, spec = str(text).partition("=")
    name = name.strip().lower()
    if not sep or not spec.strip():
        raise ParameterError(f"{text!r} is not {_VARY_SYNTAX}")
    if name not in VARY_NAMES:
        raise ParameterError(f"{text!r}: unknown parameter {name!r}; vary one of {', '.join(VARY_NAMES)}")
    parts = spec.split(":")
    if len(parts) not in (1, 3):
        raise ParameterError(f"{text!r} is not {_VARY_SYNTAX}")
    if len(parts) == 3 and not (parts[2].strip().isdigit() and int(parts[2]) >= 1):
        raise ParameterError(f"{text!r}: COUNT must be a whole number >= 1")
    if len(parts) == 3 and int(parts[2]) > MAX_VARIANTS + 1:
        # Checked before the values are made: a family never holds more.
        raise ParameterError(f"{text!r}: COUNT must be at most {MAX_VARIANTS + 1} (a family's most)")
    try:
        if len(parts) == 3:
            grid = np.linspace(float(parts[0]), float(parts[1]), int(parts[2]))
            values = tuple(round_significant(float(v), 12) for v in grid)
        else:
            values = tuple(float(v) for v in spec.split(","))
    except ValueError:
        raise ParameterError(f"{text!r} is not {_VARY_SYNTAX}") from None
    if not all(math.isfinite(v) for v in values):
        raise ParameterError(f"{text!r}: values must be finite numbers")
    return name, values


@one_blas_thread
def family(
    base: ShapeSpec,
    vary: Sequence[tuple[str, Sequence[float]]],
    *,
    absolute: bool = False,
    one_at_a_time: bool = False,
) -> list[ShapeSpec]:
    """Variants of a shape with some parameters changed (the paper's Section IV-C).

    Parameters
    ----------
    base : ShapeSpec
        A Superformula shape of a spec.
    vary : sequence of (name, values)
        As :func:`parse_vary` returns them. By default the values are factors
        on the base's parameter (``n1=0.8:1.2:5`` makes n1 from 0.8 to 1.2
        times the base's).
    absolute : bool
        The values are the parameters' values, not factors.
    one_at_a_time : bool
        Vary each name alone, the others at the base's values (the paper's
        sweeps), instead of every combination.

    Returns
    -------
    variants : list of ShapeSpec
        Named ``BASE-NAME-VALUE[-NAME-VALUE...]`` (sanitised, e.g.
        ``egg-n1-0-9`` for a factor 0.9), with the base's interest. A variant
        of the base's outline (up to a turn and a scale: a circle's n1, a
        factor within rounding of 1) is left out.

    Raises
    ------
    SpecError
        If the base is given by photos, a parameter is varied twice (in
        combinations), there would be
        more than ``MAX_VARIANTS`` variants, two names collide, a variant's m1
        or m2 is not a whole number (its curve would not close), or a variant
        is not a closed shape that encloses its centroid.
    """
    if base.params is None:
        raise SpecError(
            f"shape {base.name!r} is given by example photos; fit it first "
            "('rockscan library fit') to vary its parameters"
        )
    if not vary:
        raise SpecError("vary at least one parameter (e.g. n1=0.8:1.2:5)")
    names = [name for name, _ in vary]
    if unknown := [name for name in names if name not in VARY_NAMES]:
        raise SpecError(f"cannot vary {', '.join(map(repr, unknown))}; vary {', '.join(VARY_NAMES)}")
    touched = [p for name in names for p in VARY_NAMES[name]]
    if not one_at_a_time and len(set(touched)) != len(touched):
        raise SpecError(f"a parameter is varied twice in {', '.join(names)}; vary it once")
    if one_at_a_time:
        combos = [((name, v),) for name, values in vary for v in values]
    else:
        combos = [()]
        for name, values in vary:
            combos = [(*c, (name, v)) for c in combos for v in values]
            if len(combos) > MAX_VARIANTS:
                break
    if len(combos) > MAX_VARIANTS:
        raise SpecError(f"that family would hold over {MAX_VARIANTS} variants; vary fewer values")
    base_values = base.params.as_dict()
    base_radii = shape_radii(base.params, 360)
    variants: list[ShapeSpec] = []
    seen: dict[str, tuple[tuple[str, float], ...]] = {}
    for combo in combos:
        values = dict(base_values)
        for name, v in combo:
            for key in VARY_NAMES[name]:
                # Twelve digits keep 1500 * 1.1 at 1650 in the spec, not 1650.0000000000002.
                values[key] = v if absolute else round_significant(base_values[key] * v, 12)
        if values == base_values:
            continue
        if broken := [k for k in ("m1", "m2") if values[k] != round(values[k])]:
            # A curve of m = 3.6 does not close: a step at theta = 0, drawn and matched as it is.
            raise SpecError(
                f"{broken[0]} = {values[broken[0]]:g} would not close the curve: m1 and m2 are whole "
                "numbers; vary them by value (e.g. --vary m=3,4,5 --absolute)"
            )
        label = "-".join(f"{name}-{_value_label(v)}" for name, v in combo)
        variant_name = sanitize_name(f"{base.name}-{label}")
        if variant_name in seen:
            raise SpecError(
                f"variants {seen[variant_name]} and {combo} would both be named {variant_name!r}; "
                "use values that differ in their first 6 digits"
            )
        seen[variant_name] = combo
        try:
            params = SuperformulaParams(**values)
            radii = shape_radii(params, 360)
        except ParameterError as exc:
            raise SpecError(f"variant {variant_name!r}: {exc}; narrow the --vary range") from None
        if _same_outline(radii, base_radii):
            # A circle's n1, or a factor within rounding of 1: the base itself,
            # which library build would refuse beside it.
            continue
        variants.append(ShapeSpec(variant_name, params, interest=base.interest))
    return variants


def _same_outline(radii: NDArray[np.float64], base: NDArray[np.float64]) -> bool:
    """Whether two outlines are one, up to a turn (log radii within ``SAME_OUTLINE``)."""
    a, b = np.log(radii), np.log(base)
    a, b = a - a.mean(), b - b.mean()
    # Every turn at once: the circular cross-correlation gives |a - roll(b)|**2.
    cross = np.fft.irfft(np.fft.rfft(a) * np.conj(np.fft.rfft(b)), n=a.size)
    return bool(float(a @ a + b @ b - 2.0 * cross.max()) < SAME_OUTLINE**2 * a.size)


#: RMS difference of centred log radii under which a variant is its base: a
#: factor of 1 + 1e-7 on the egg's n1 differs by 8e-9, one of 1.001 by 8e-5.
SAME_OUTLINE = 1e-6


def _value_label(value: float) -> str:
    """A value as it reads in a variant's name: ``0.9`` -> ``0.9`` (sanitised to
    ``0-9``), ``1e+308`` -> ``1e308`` and ``-2`` -> ``m2``, so that sanitising
    the name turns neither a sign nor an exponent into a dash that reads as
    the opposite sign."""
    text = f"{value:g}".replace("e+", "e")
    return "m" + text[1:] if text.startswith("-") else text
