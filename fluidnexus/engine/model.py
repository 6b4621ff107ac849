"""Configuration of the PBF gas: the solver constants and the model (which external terms, which parameters).

Both are frozen dataclasses that round-trip through plain dicts (JSON), so a fitted model is saved as
``model.json`` and reloaded with :meth:`ModelConfig.from_dict`. Constants are in metres; the release works
in a x100 scaled space (centimetres) and docs/simulator.md gives the conversion of each constant.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np

from .ambient import AmbientAir, structure_from_dict, structure_to_dict
from .entrainment import Entrainment
from .forces import TERMS, Buoyancy, Drag
from .sph import lattice_density


@dataclass(frozen=True)
class SolverConfig:
    """PBF density solver (Macklin & Mueller 2013; FluidNexus Eq. S1-S3).

    Attributes:
        h: kernel support radius H [m].
        rest_density: rho0 [1/m^3] (unit-mass number density). Default: the release's ScalarFlow 2.0 per
            cm^3 = 2.0e6 per m^3, i.e. 1.44 x the Poly6 density of the 0.009 m initial lattice
            (see :func:`rest_density_for_lattice`).
        eps: constraint relaxation epsilon [1/m^2] (release: 0.01 cm^-2 = 100 m^-2).
        iterations: solver iterations per step.
        scorr_k: tensile-correction strength K [m^2] (release: K = 0.2 in cm^2 = 2e-5 m^2).
        scorr_n: tensile-correction exponent n.
        scorr_dq: tensile-correction reference distance as a fraction of h.
        averaging: divide each particle's position correction by its neighbour count (the release's
            Flex-style constraint averaging).
        dt: time step [s] (1 / fps).
    """

    h: float = 0.02
    rest_density: float = 2.0e6
    eps: float = 100.0
    iterations: int = 10
    scorr_k: float = 2.0e-5
    scorr_n: int = 4
    scorr_dq: float = 0.25
    averaging: bool = True
    dt: float = 1.0 / 30.0

    def __post_init__(self):
        if self.h <= 0 or self.rest_density <= 0 or self.dt <= 0 or self.eps < 0:
            raise ValueError(f"invalid solver constants: {self}")
        if self.iterations < 0:
            raise ValueError(f"iterations must be >= 0, got {self.iterations}")

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "SolverConfig":
        unknown = set(d) - {f.name for f in fields(cls)}
        if unknown:
            raise ValueError(f"unknown solver keys: {sorted(unknown)}")
        return cls(**d)


def rest_density_for_lattice(spacing: float, h: float, ratio: float) -> float:
    """rho0 = ``ratio`` x the Poly6 density of an interior particle of a cubic lattice of ``spacing`` [m]."""
    return ratio * lattice_density(spacing, h)


def _param_size(value) -> int:
    return len(value) if isinstance(value, (tuple, list)) else 1


@dataclass(frozen=True)
class ModelConfig:
    """Which external terms act on the gas, in order, with their parameters, and the model structure.

    The differentiable parameters of all terms form one flat vector ``theta`` (see :meth:`param_names`,
    :meth:`to_vector`, :meth:`with_vector`); gradients of a loss come back in that layout.

    ``air`` selects the structure: None is the paper's gas (``paper_gas``: smoke particles in empty space), an
    :class:`~fluidnexus.engine.ambient.AmbientAir` the gas in ambient air (``ambient_air``, engine/ambient.py).
    ``entrainment``: the paper's gas taking in ambient air between steps (engine/entrainment.py), or None.
    """

    terms: tuple = field(default_factory=lambda: (Buoyancy(), Drag()))
    air: AmbientAir | None = None
    entrainment: Entrainment | None = None

    def __post_init__(self):
        kinds = [t.kind for t in self.terms]
        if len(set(kinds)) != len(kinds):
            raise ValueError(f"each term kind may appear once, got {kinds}")
        if self.entrainment is not None and self.air is not None:
            raise ValueError("entrainment is a term of the paper's gas; the gas in ambient air entrains its air")

    @classmethod
    def scalarflow(cls) -> "ModelConfig":
        """The paper's ScalarFlow model: buoyancy alpha = -3 in the release's x100 space (alpha = -0.03 with g in
        m/s^2, i.e. 0.29 m/s^2 upward), drag k = 3 1/s in still air."""
        return cls((Buoyancy(alpha=-0.03), Drag(k=3.0)))

    @property
    def structure(self) -> str:
        """``"paper_gas"`` or ``"ambient_air"``."""
        return "paper_gas" if self.air is None else self.air.name

    def term(self, kind: str):
        for t in self.terms:
            if t.kind == kind:
                return t
        raise KeyError(kind)

    def param_names(self) -> list[str]:
        """Names of the entries of ``theta``, e.g. ``drag.v_env[1]``."""
        names = []
        for t in self.terms:
            for p in t.params:
                v = getattr(t, p)
                n = _param_size(v)
                names += [f"{t.kind}.{p}"] if n == 1 else [f"{t.kind}.{p}[{k}]" for k in range(n)]
        return names

    def offsets(self) -> list[int]:
        """Offset of each term's first parameter in ``theta``."""
        out, off = [], 0
        for t in self.terms:
            out.append(off)
            off += sum(_param_size(getattr(t, p)) for p in t.params)
        return out

    def to_vector(self) -> np.ndarray:
        """The differentiable parameters as a float64 vector [P]."""
        vals = []
        for t in self.terms:
            for p in t.params:
                vals += list(np.atleast_1d(np.asarray(getattr(t, p), dtype=np.float64)))
        return np.asarray(vals, dtype=np.float64)

    def with_vector(self, theta) -> "ModelConfig":
        """A copy whose differentiable parameters are taken from ``theta`` [P] (same layout)."""
        theta = np.asarray(theta, dtype=np.float64).ravel()
        if theta.size != len(self.param_names()):
            raise ValueError(f"theta has {theta.size} entries, the model has {len(self.param_names())}")
        terms, k = [], 0
        for t in self.terms:
            upd = {}
            for p in t.params:
                n = _param_size(getattr(t, p))
                upd[p] = float(theta[k]) if not isinstance(getattr(t, p), (tuple, list)) else \
                    tuple(float(x) for x in theta[k:k + n])
                k += n
            terms.append(replace(t, **upd))
        return replace(self, terms=tuple(terms))

    def to_dict(self) -> dict:
        """Plain-dict form: ``{"terms": [{"kind": ..., <params>}, ...], "structure": {"name": ..., <params>}}``,
        plus ``"entrainment": {"alpha": ...}`` when the model has it."""
        out = []
        for t in self.terms:
            d = {"kind": t.kind}
            for f in fields(t):
                v = getattr(t, f.name)
                d[f.name] = list(v) if isinstance(v, tuple) else v
            out.append(d)
        out = {"terms": out, "structure": structure_to_dict(self.air)}
        if self.entrainment is not None:
            out["entrainment"] = self.entrainment.to_dict()
        return out

    @classmethod
    def from_dict(cls, d: dict) -> "ModelConfig":
        """The inverse of :meth:`to_dict`; a dict without ``structure`` (older model.json) is the paper's gas."""
        terms = []
        for entry in d.get("terms", []):
            entry = dict(entry)
            kind = entry.pop("kind", None)
            if kind not in TERMS:
                raise ValueError(f"unknown term kind {kind!r}; known: {sorted(TERMS)}")
            cls_ = TERMS[kind]
            names = {f.name for f in fields(cls_)}
            unknown = set(entry) - names
            if unknown:
                raise ValueError(f"unknown keys for term {kind!r}: {sorted(unknown)}")
            terms.append(cls_(**{k: tuple(v) if isinstance(v, list) else v for k, v in entry.items()}))
        entrainment = d.get("entrainment")
        if entrainment is not None:
            unknown = set(entrainment) - {"alpha"}
            if unknown:
                raise ValueError(f"unknown keys for entrainment: {sorted(unknown)}")
            entrainment = Entrainment(**entrainment)
        return cls(tuple(terms), structure_from_dict(d.get("structure", {"name": "paper_gas"})), entrainment)
