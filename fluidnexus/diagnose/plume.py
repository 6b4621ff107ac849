"""The simulated plume of diagnose in one of two structures, with the candidate extensions, rolled forward and
rendered into the observation views.

- ``paper_gas``: the paper's PBF gas (buoyancy alpha, drag k) emitted by the scene's source disk;
- ``ambient_air``: the gas in ambient air (engine/ambient.py: buoyancy alpha on smoke, XSPH viscosity c among
  smoke and air, the source as an inlet of speed ``inflow``), on a lattice ``AIR_SPACING`` x coarser.

The rollout is the engine's PBF step (FluidNexus Eq. S1-S4) at a coarse particle spacing; the smoke seen in
the images is carried by the smoke particles themselves, each with brightness ``gain * exp(-rate * age)``.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from itertools import islice

import numpy as np

from fluidnexus.engine import (AirDomain, AmbientAir, Buoyancy, Drag, Entrainment, ModelConfig, PBFSimulator,
                               PhysicalParticles, SolverConfig, SourceDisk, Viscosity, Vorticity, prune,
                               rest_density_for_lattice, step_particles)
from fluidnexus.scenery.world import Obstacles

from .observe import splat_points

#: The candidate extensions: name -> its parameters (defaults = the term switched off). See docs/diagnose.md.
EXTENSIONS = {
    "wind": {"velocity": (0.0, 0.0, 0.0)},   # ambient air velocity [m/s], drag v_env (Eq. S4)
    "buoyancy_decay": {"tau": np.inf},        # e-folding time of buoyancy with particle age [s]
    "vorticity": {"epsilon": 0.0},            # vorticity confinement strength [m/s]
    "viscosity": {"c": 0.0},                  # XSPH viscosity coefficient
    "dissipation": {"rate": 0.0},             # smoke fading [1/s]
    "swirl": {"omega": 0.0},                  # inflow angular velocity about +y [rad/s]
    "entrainment": {"alpha": 0.0},            # entrainment coefficient (engine/entrainment.py; paper_gas only)
}
#: The extensions that extend only the paper's gas (the gas in ambient air entrains its own air).
PAPER_GAS_ONLY = ("entrainment",)
#: The base structures (engine/ambient.py): the paper's gas in empty space, the gas in ambient air.
STRUCTURES = ("paper_gas", "ambient_air")
#: The ambient-air structure's lattice ratios follow this multiple of ``--spacing`` (0.03 m for the default 0.02 m):
#: its air costs several thousand particles per plume (docs/diagnose.md).
AIR_SPACING = 1.5


@dataclass(frozen=True)
class PlumeParams:
    """Parameters of the simulated plume.

    Attributes:
        alpha: buoyancy coefficient (< 0 rises; FluidNexus Eq. S1).
        k: drag coefficient [1/s] (Eq. S4; paper_gas only).
        layers: source rate: disk layers emitted per second (at most one per step); the layers leave the
            source at the inflow speed ``layers x spacing`` m/s so that they do not pile up (paper_gas only).
        gain: brightness of one particle's smoke; fitted in closed form.
        extensions: active extensions, name -> {param: value} (names and parameters of :data:`EXTENSIONS`).
        structure: ``paper_gas`` or ``ambient_air`` (:data:`STRUCTURES`).
        inflow: the inlet speed [m/s] (ambient_air only).
        c: XSPH viscosity among smoke and air (ambient_air only; the ``viscosity`` extension refits it).
    """

    alpha: float = -3.0
    k: float = 3.0
    layers: float = 10.0
    gain: float = 1.0
    extensions: dict = field(default_factory=dict)
    structure: str = "paper_gas"
    inflow: float = 0.25
    c: float = 0.0

    def ext(self, name: str, key: str):
        return self.extensions.get(name, EXTENSIONS[name])[key]

    def model(self) -> ModelConfig:
        """The engine model of these parameters (the extensions that are forces included)."""
        tau = self.ext("buoyancy_decay", "tau")
        buoyancy = Buoyancy(alpha=self.alpha, decay=0.0 if not np.isfinite(tau) else 1.0 / tau)
        wind = tuple(float(v) for v in self.ext("wind", "velocity"))
        if self.structure == "ambient_air":  # wind is the air's motion; XSPH among smoke and air is in the base
            c = float(self.ext("viscosity", "c")) if "viscosity" in self.extensions else self.c
            terms = [buoyancy, Viscosity(c=c)]
            if "vorticity" in self.extensions:
                terms.append(Vorticity(epsilon=float(self.ext("vorticity", "epsilon"))))
            return ModelConfig(tuple(terms), AmbientAir(inflow=self.inflow, wind=wind))
        terms = [buoyancy, Drag(k=self.k, v_env=wind)]
        if "vorticity" in self.extensions:
            terms.append(Vorticity(epsilon=float(self.ext("vorticity", "epsilon"))))
        if "viscosity" in self.extensions:
            terms.append(Viscosity(c=float(self.ext("viscosity", "c"))))
        entrainment = Entrainment(float(self.ext("entrainment", "alpha"))) if "entrainment" in self.extensions else None
        return ModelConfig(tuple(terms), entrainment=entrainment)

    def with_gain(self, gain: float) -> "PlumeParams":
        return replace(self, gain=float(gain))

    def identity(self) -> str:
        """What decides this model's rollout and its images up to their brightness: the parameters with the gain
        left out and every extension at its null value dropped (the defaults of :data:`EXTENSIONS`; the gas in
        ambient air's viscosity at its base's ``c``), since such a term reproduces the model without it exactly
        (tests/diagnose/test_diagnose_null.py). Two parameter sets with the same identity score the same."""
        def null(name, values):
            default = {"c": self.c} if name == "viscosity" and self.structure == "ambient_air" else EXTENSIONS[name]
            return all(np.all(np.asarray(values[k]) == np.asarray(v)) for k, v in default.items())

        def exact(values) -> tuple:  # every value in full (repr of an array or a float32 rounds)
            return tuple(float(v).hex() for v in np.ravel(np.asarray(values, np.float64)))

        terms = tuple((name, tuple((k, exact(v)) for k, v in sorted(values.items())))
                      for name, values in sorted(self.extensions.items()) if not null(name, values))
        return repr((self.structure, exact([self.alpha, self.k, self.layers, self.inflow, self.c]), terms))


@dataclass(frozen=True)
class PlumeSetup:
    """What every rollout shares.

    Attributes:
        source_center: inflow disk centre [m]; source_radius: its radius [m].
        spacing: physical particle spacing [m] (the solver's H and rho0 follow it, docs/simulator.md ratios).
        fps: frame rate; a rollout takes one step per frame.
        frames: number of frames rolled out (the first is the initial state).
        lo, hi: particles leaving this box [m] are removed.
        seed: [M, 3] particles present at the first frame (e.g. from the visual hull) [m].
        air_seed: the same for the ambient-air structure, on its coarser lattice [m].
        iterations: PBF solver iterations per step.
        emitting: [frames] bool, whether the source emits in the step into each frame (the emission window,
            emission.py); None: in every step.
        obstacles: where the bodies the plume flows around come from (scenery.Obstacles), or None.
    """

    source_center: tuple
    source_radius: float
    spacing: float
    fps: float
    frames: int
    lo: tuple
    hi: tuple
    seed: np.ndarray
    air_seed: np.ndarray
    iterations: int = 4
    emitting: np.ndarray | None = None
    obstacles: Obstacles | None = None

    def emits(self, frame: int) -> bool:
        """Whether the source emits in the step into rollout frame ``frame``."""
        return self.emitting is None or bool(self.emitting[frame])

    def solver_for(self, structure: str) -> SolverConfig:
        """The solver of a structure: H and rho0 follow its lattice (``spacing``, or ``AIR_SPACING`` x coarser)."""
        spacing = self.spacing * (AIR_SPACING if structure == "ambient_air" else 1.0)
        h = spacing / 0.45  # the release's 0.009 m lattice at H = 0.02 m
        return SolverConfig(h=h, rest_density=rest_density_for_lattice(spacing, h, 1.44),
                            iterations=self.iterations, dt=1.0 / self.fps)

    @property
    def solver(self) -> SolverConfig:
        return self.solver_for("paper_gas")

    def domain(self, air: AmbientAir, obstacle=None) -> AirDomain:
        """The air around the source (ambient_air), inside the box [lo, hi], none inside ``obstacle``."""
        s = self.solver_for("ambient_air")
        return AirDomain(air, s.h, s.rest_density, s.dt, self.source_center, self.source_radius, self.lo, self.hi,
                         obstacle)

    @property
    def source(self) -> SourceDisk:
        return SourceDisk(center=tuple(self.source_center), radius=self.source_radius, spacing=self.spacing)

    @property
    def capacity(self) -> int:
        return len(self.seed) + self.source.count * self.frames


@dataclass
class Rollout:
    """Particle positions [N_t, 3] m and ages [N_t] s at each frame of a rollout (the first frames of it while
    ``rest`` still holds frames to simulate)."""

    positions: list
    ages: list
    rest: Iterator | None = None

    @classmethod
    def start(cls, frames: Iterator, count: int | None = None) -> "Rollout":
        """The first ``count`` frames (None: all) of ``frames`` (:meth:`PlumeSimulator.frames`)."""
        out = cls([], [], frames)
        out.extend(count)
        return out

    def extend(self, count: int | None = None) -> None:
        """Simulate on until the rollout has ``count`` frames (None: all). The simulator is shared: extend a
        rollout only before the next one starts."""
        if self.rest is None:
            return
        for positions, ages in self.rest if count is None else islice(self.rest, max(count - len(self), 0)):
            self.positions.append(positions)
            self.ages.append(ages)
        if count is None:
            self.rest = None

    def __len__(self) -> int:
        return len(self.positions)


class PlumeSimulator:
    """Rolls the plume forward; keeps one engine simulator per structure, its terms set per model."""

    def __init__(self, setup: PlumeSetup, obstacle=None):
        """``obstacle``: the engine body of ``setup.obstacles`` when this process has built it already."""
        self.setup = setup
        self._sims: dict = {}
        self._particles = PhysicalParticles(setup.capacity)
        if obstacle is None and setup.obstacles is not None:
            obstacle = setup.obstacles.body()
        self.obstacle = obstacle

    def _simulator(self, model: ModelConfig, capacity: int) -> PBFSimulator:
        sim = self._sims.get(model.structure)
        if sim is None or sim.capacity < capacity:
            sim = self._sims[model.structure] = PBFSimulator(capacity, self.setup.solver_for(model.structure), model)
            sim.set_obstacle(self.obstacle)
        else:
            sim.set_model(model)  # its terms and parameters (the entrainment too, which is no kernel term)
        return sim

    def frames(self, params: PlumeParams) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """(positions [N, 3] m, ages [N] s) of the smoke at each of ``setup.frames`` frames in turn, each step
        simulated only when its frame is asked for (one PBF step per frame; emission before each step inside
        the emission window: paper_gas's disk layers, ambient_air's inlet). The simulator's particles are
        shared: one sequence at a time."""
        if params.structure == "ambient_air":
            yield from self._frames_air(params)
            return
        s = self.setup
        sim = self._simulator(params.model(), s.capacity)
        particles = self._particles
        particles.keep(np.zeros(particles.n, bool))
        if len(s.seed):
            particles.add(position=s.seed)
        rng = np.random.default_rng(0)
        source, omega = s.source, float(params.ext("swirl", "omega"))
        per_step = min(max(params.layers, 0.0) / s.fps, 1.0)
        inflow = per_step * s.fps * s.spacing
        phase = 1.0
        yield particles.get("position").copy(), particles.get("age").ravel().copy()
        for t in range(1, s.frames):
            on = s.emits(t)
            phase += per_step if on else 0.0
            if on and phase >= 1.0:
                phase -= 1.0
                pts = source.sample(rng)
                r = pts - np.asarray(s.source_center)
                # inflow speed upwards plus angular velocity omega about +y: v = (0, omega, 0) x r
                vel = np.stack([omega * r[:, 2], np.full(len(r), inflow), -omega * r[:, 0]], -1)
                particles.add(position=pts, velocity=vel)
            step_particles(sim, particles)
            prune(particles, None, s.solver.h, s.lo, s.hi)
            yield particles.get("position").copy(), particles.get("age").ravel().copy()

    def _frames_air(self, params: PlumeParams) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """The gas in ambient air: the seed as smoke in air at rest, the inlet (with the swirl) feeding it."""
        s, model = self.setup, params.model()
        domain = s.domain(model.air, self.obstacle)
        sim = self._simulator(model, domain.capacity(len(s.air_seed)))
        state = domain.initial(s.air_seed)
        omega = float(params.ext("swirl", "omega"))
        yield state.p[state.is_smoke].copy(), state.age[state.is_smoke].copy()
        for t in range(1, s.frames):
            state = domain.step(sim, state, omega, inflow=s.emits(t))
            yield state.p[state.is_smoke].copy(), state.age[state.is_smoke].copy()


def render_rollout(rollout: Rollout, params: PlumeParams, cameras, sigma_px: float, start: int = 0) -> np.ndarray:
    """Images [V, T - start, h, w] of a rollout's frames from ``start`` on: each particle carries
    ``gain * exp(-rate * age)`` smoke."""
    rate = float(params.ext("dissipation", "rate"))
    out = np.zeros((len(cameras), len(rollout) - start, cameras[0].height, cameras[0].width))
    for t in range(start, len(rollout)):
        w = params.gain * np.exp(-rate * rollout.ages[t])
        for v, cam in enumerate(cameras):
            out[v, t - start] = splat_points(cam, rollout.positions[t], w, sigma_px)
    return out
