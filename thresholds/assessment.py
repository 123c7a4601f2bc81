"""Result types of the safety criteria: which rule fired, where, and by how much.

Every criterion (IMO MSC.1/Circ.1228 in :mod:`thresholds.imo_msc1228`, operator limits in
:mod:`thresholds.operator`) returns a :class:`RuleResult`; an evaluation of several rules is an
:class:`Assessment`, which also packs the fired rules into one integer **reason code** per cell
(a bit mask, :data:`REASON_BITS`) so a whole grid can be stored, compared and explained cheaply.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: One bit per rule. ``no_data`` marks cells where an input needed by an active rule is NaN
#: (land, or outside the data): such a cell is never reported safe.
REASON_BITS: dict[str, int] = {
    "hs": 1 << 0,
    "period": 1 << 1,
    "wind": 1 << 2,
    "beam_seas": 1 << 3,
    "surf_riding": 1 << 4,
    "high_waves": 1 << 5,
    "synchronous_roll": 1 << 6,
    "parametric_roll": 1 << 7,
    "no_data": 1 << 15,
}

#: Short human explanations, used by reports.
REASON_TEXT: dict[str, str] = {
    "hs": "significant wave height above the operator limit",
    "period": "wave period outside the operator's allowed range",
    "wind": "mean wind speed above the operator limit",
    "beam_seas": "beam seas (relative wave direction in a forbidden sector)",
    "surf_riding": "surf-riding / broaching-to risk (IMO MSC.1/Circ.1228)",
    "high_waves": "successive high-wave attack (IMO MSC.1/Circ.1228)",
    "synchronous_roll": "synchronous rolling (IMO MSC.1/Circ.1228)",
    "parametric_roll": "parametric rolling (IMO MSC.1/Circ.1228)",
    "no_data": "weather missing (land or outside the data)",
}


def reason_names(code: int) -> list[str]:
    """The rule names packed in one reason code, in :data:`REASON_BITS` order.

    Examples
    --------
    >>> reason_names(REASON_BITS["hs"] | REASON_BITS["beam_seas"])
    ['hs', 'beam_seas']
    """
    code = int(code)
    return [name for name, bit in REASON_BITS.items() if code & bit]


@dataclass(frozen=True)
class RuleResult:
    """Outcome of one criterion over an array of cases.

    Attributes
    ----------
    name : str
        Rule name, a key of :data:`REASON_BITS`.
    fired : ndarray of bool
        True where the rule is broken. NaN inputs never fire (see :class:`Assessment` ``no_data``).
    margin : ndarray of float
        Signed distance to the rule's boundary, positive when it fires, in ``margin_unit``
        (``"m"``, ``"s"``, ``"ms"``, ``"kn"``, ``"deg"`` or ``"frac"`` = fraction of the limit).
    margin_unit : str
    value : ndarray of float
        The quantity compared (Hs, speed, encounter period ...).
    limit : ndarray of float
        What it was compared with (NaN where the rule does not apply).
    """

    name: str
    fired: np.ndarray
    margin: np.ndarray
    margin_unit: str
    value: np.ndarray
    limit: np.ndarray

    def __post_init__(self):
        if self.name not in REASON_BITS:
            raise ValueError(f"unknown rule name {self.name!r}; known: {', '.join(REASON_BITS)}")
        shape = np.broadcast_shapes(*(np.shape(x) for x in (self.fired, self.margin, self.value, self.limit)))
        object.__setattr__(self, "fired", np.broadcast_to(np.asarray(self.fired, dtype=bool), shape))
        for key in ("margin", "value", "limit"):
            object.__setattr__(self, key, np.broadcast_to(np.asarray(getattr(self, key), dtype=float), shape))

    @property
    def bit(self) -> int:
        return REASON_BITS[self.name]


@dataclass(frozen=True)
class Assessment:
    """Several rules evaluated over the same cases.

    Attributes
    ----------
    rules : dict of str -> RuleResult
        One entry per rule evaluated (rules whose inputs were not given are absent).
    no_data : ndarray of bool
        Cases where an input of an evaluated rule was NaN.
    skipped : tuple of str
        Rules that were not evaluated and why (``"synchronous_roll: no GM or roll period"``), so a
        report never presents an unevaluated rule as passed.
    """

    rules: dict = field(default_factory=dict)
    no_data: np.ndarray | None = None
    skipped: tuple = ()

    @property
    def shape(self) -> tuple:
        shapes = [np.shape(r.fired) for r in self.rules.values()]
        if self.no_data is not None:
            shapes.append(np.shape(self.no_data))
        return np.broadcast_shapes(*shapes) if shapes else ()

    @property
    def reason_code(self) -> np.ndarray:
        """Bit mask per case (uint16): OR of the bits of the rules that fired, plus ``no_data``."""
        code = np.zeros(self.shape, dtype=np.uint16)
        for rule in self.rules.values():
            code |= np.where(rule.fired, np.uint16(rule.bit), np.uint16(0)).astype(np.uint16)
        if self.no_data is not None:
            code |= np.where(self.no_data, np.uint16(REASON_BITS["no_data"]), np.uint16(0)).astype(np.uint16)
        return code

    @property
    def unsafe(self) -> np.ndarray:
        """True where any rule fired or data were missing."""
        return self.reason_code != 0

    @property
    def safe(self) -> np.ndarray:
        return ~self.unsafe

    def fired(self, name: str) -> np.ndarray:
        return self.rules[name].fired

    def margin(self, name: str) -> np.ndarray:
        return self.rules[name].margin

    def merge(self, other: "Assessment") -> "Assessment":
        """Union of two assessments over the same cases (later rules of the same name win)."""
        nd = [x for x in (self.no_data, other.no_data) if x is not None]
        no_data = None if not nd else np.logical_or.reduce(np.broadcast_arrays(*nd))
        return Assessment({**self.rules, **other.rules}, no_data, tuple(self.skipped) + tuple(other.skipped))

    def explain(self, index=()) -> list[dict]:
        """The rules that fired at one case, with value, limit and margin (for reports).

        Examples
        --------
        >>> from thresholds.operator import OperatorLimits, evaluate_operator
        >>> lim = OperatorLimits(name="x", hs_max_m=6.0)
        >>> evaluate_operator(lim, hs_m=7.5).explain()[0]["rule"]
        'hs'
        """
        out = []
        for name, rule in self.rules.items():
            if bool(rule.fired[index]):
                out.append(
                    {
                        "rule": name,
                        "text": REASON_TEXT[name],
                        "value": float(rule.value[index]),
                        "limit": float(rule.limit[index]),
                        "margin": float(rule.margin[index]),
                        "margin_unit": rule.margin_unit,
                    }
                )
        if self.no_data is not None and bool(np.broadcast_to(self.no_data, self.shape)[index]):
            out.append({"rule": "no_data", "text": REASON_TEXT["no_data"]})
        return out
