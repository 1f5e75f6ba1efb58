"""Constitutive laws of the MPM engine: a registry with one entry per law, and their Warp functions.

Every law is a compressible hyperelastic solid W(F) = W_iso + K/2 (J - 1)^2 with J = det F, C = F^T F,
I1 = tr C, I2 = (I1^2 - tr C^2) / 2 and the isochoric invariants I1b = J^(-2/3) I1, I2b = J^(-4/3) I2
(2D is plane strain: F_zz = 1); the isochoric invariants separate the deviatoric and volumetric responses, as in
the incompressible fits of seed 001. The kinematics and the volumetric part are shared; a law supplies W_iso.
Units: moduli and parameters in Pa, W in J/m^3 of reference volume, first Piola stress P = dW/dF in Pa.

Each particle carries its law's ``code``, its initial shear modulus G (Pa: the Neo-Hookean modulus; for every
law it sets the time step), its bulk modulus K (Pa, default 20 G) and three law numbers ``prm`` (Pa), packed by
:meth:`MaterialLaw.pack` from the scene keys.

Adding a law:

1. An entry in ``LAWS`` below: scene name, the next free code, its parameters (scene key, unit, a typical
   value for the tests), which of them fill the three engine numbers, its initial shear modulus (the
   small-strain slope of shear stress, Pa) and the condition on the parameters that keeps that modulus > 0.
2. Its two Warp functions in :func:`make_material_functions`, ``<law>_stress`` and ``<law>_energy``, with the
   signatures of the existing ones, listed in the ``functions`` table there. Compute constants in Python
   (double) outside the functions: literal arithmetic inside a Warp function runs in float32.
3. A new parameter key also needs its field in ``Material`` (scene/schema.py); name the law in that class's
   docstring and regenerate docs/scenes.md (``magsoro docs scenes --out docs/scenes.md``), which lists the
   model names.

tests/test_material_registry.py then checks every entry: stress = dW/dF, its initial shear modulus, the schema.
"""

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass


@dataclass(frozen=True)
class Parameter:
    """A scene key of a law (a field of the scene's Material table)."""

    key: str
    unit: str
    description: str
    example: float  # a typical value, used by the tests
    required: bool = True  # an inline scene table must give it
    default: float | None = None  # value when a material file lacks it; None: it must be there


@dataclass(frozen=True)
class MaterialLaw:
    """One constitutive law: its scene name, engine code and parameters.

    ``engine_params`` names the parameter packed into each of the three engine numbers (None: 0).
    ``shear`` gives the initial shear modulus (Pa) from the parameters as floats; ``constraint`` states the
    condition on the parameters equivalent to it being > 0. ``read_fit`` turns a `magsoro fit-material` entry
    into scene keys when its [parameters] are not already the law's keys.
    """

    name: str
    code: int
    title: str
    description: str
    parameters: tuple[Parameter, ...]
    engine_params: tuple[str | None, str | None, str | None]
    shear: Callable[[dict], float]
    constraint: str
    read_fit: Callable[[dict], dict] | None = None

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(p.key for p in self.parameters)

    @property
    def required(self) -> tuple[str, ...]:
        return tuple(p.key for p in self.parameters if p.required)

    def values(self, given: Mapping) -> dict[str, float]:
        """The law's parameters as floats (Pa), defaults for those ``given`` lacks; KeyError names a missing one."""
        return {p.key: float(given[p.key] if p.key in given or p.default is None else p.default) for p in self.parameters}

    def initial_shear_modulus(self, given: Mapping) -> float:
        """Small-strain shear modulus, Pa."""
        return self.shear(self.values(given))

    def pack(self, given: Mapping) -> tuple[float, float, float]:
        """The three engine numbers (Pa) of the particles' ``material_params``."""
        v = self.values(given)
        return tuple(0.0 if k is None else v[k] for k in self.engine_params)

    def from_material_file(self, entry: dict) -> dict:
        """Scene keys of this law from a `magsoro fit-material` entry."""
        if self.read_fit is not None:
            return self.read_fit(entry)
        params = entry.get("parameters", {})
        return {k: params[k] for k in self.keys if k in params}


def _neo_hookean_from_fit(entry: dict) -> dict:
    # the fit writes W = C10 (I1 - 3), so G = 2 C10; otherwise the entry's initial shear modulus
    params = entry.get("parameters", {})
    return {"shear_modulus": 2.0 * params["C10"] if "C10" in params else entry.get("shear_modulus")}


def _registry(*laws: MaterialLaw) -> dict[str, MaterialLaw]:
    out = {law.name: law for law in laws}
    if len(out) != len(laws) or sorted(law.code for law in laws) != list(range(len(laws))):
        raise ValueError("material laws need distinct names and codes 0 .. n-1")
    for law in laws:
        if len(law.engine_params) != 3 or not set(law.engine_params) - {None} <= set(law.keys):
            raise ValueError(f"{law.name}: engine_params must be 3 of its parameter keys or None")
    return out


LAWS: dict[str, MaterialLaw] = _registry(
    MaterialLaw(
        name="neo-hookean",
        code=0,
        title="Neo-Hookean",
        description="W = G/2 (I1b - 3) (seed 000 eq 10)",
        parameters=(Parameter("shear_modulus", "Pa", "shear modulus G", 3.0e5),),
        engine_params=(None, None, None),  # the engine reads G from the particle's shear modulus
        shear=lambda p: p["shear_modulus"],
        constraint="shear_modulus > 0",
        read_fit=_neo_hookean_from_fit,
    ),
    MaterialLaw(
        name="mooney-rivlin",
        code=1,
        title="Mooney-Rivlin",
        description="W = C10 (I1b - 3) + C01 (I2b - 3)",
        parameters=(
            Parameter("C10", "Pa", "first-invariant modulus", 1.1e5),
            Parameter("C01", "Pa", "second-invariant modulus", 0.4e5, default=0.0),
        ),
        engine_params=("C10", "C01", None),
        shear=lambda p: 2.0 * (p["C10"] + p["C01"]),
        constraint="C10 + C01 > 0",
    ),
    MaterialLaw(
        name="yeoh",
        code=2,
        title="Yeoh",
        description="W = C10 (I1b - 3) + C20 (I1b - 3)^2 + C30 (I1b - 3)^3",
        parameters=(
            Parameter("C10", "Pa", "linear coefficient", 1.2e5),
            Parameter("C20", "Pa", "quadratic coefficient", -2.0e3, required=False, default=0.0),
            Parameter("C30", "Pa", "cubic coefficient", 4.0e2, required=False, default=0.0),
        ),
        engine_params=("C10", "C20", "C30"),
        shear=lambda p: 2.0 * p["C10"],
        constraint="C10 > 0",
    ),
)

DEFAULT_LAW = "neo-hookean"  # also the law of material library entries (they give a shear modulus)
LAW_NAMES = tuple(LAWS)
# every parameter key of every law, in registry order
PARAMETER_KEYS = tuple(dict.fromkeys(k for law in LAWS.values() for k in law.keys))


def describe_codes() -> str:
    """'0 (Neo-Hookean), 1 (Mooney-Rivlin) or 2 (Yeoh)'."""
    items = [f"{law.code} ({law.title})" for law in sorted(LAWS.values(), key=lambda law: law.code)]
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " or " + items[-1]


@functools.cache
def make_material_functions(dim: int, scalar):
    """Warp functions ``elastic_stress(F, model, G, K, prm)`` (first Piola stress, Pa) and ``elastic_energy``
    (same arguments; J/m^3) for ``dim`` in (2, 3) and ``scalar`` in (wp.float32, wp.float64), dispatching on the
    law code ``model``; also ``invariants`` and, per law name, its (stress, energy) pair."""
    import warp as wp

    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim}")
    mat = wp.types.matrix(shape=(dim, dim), dtype=scalar)
    v3 = wp.types.vector(length=3, dtype=scalar)
    # Constants are computed here in double precision: literal arithmetic inside a Warp function runs in float32.
    minus_two_thirds = -2.0 / 3.0

    @wp.func
    def invariants(F: mat):
        """J, I1 = tr C and tr(C^2) of C = F^T F; in 2D (plane strain) F_zz = 1 adds 1 to both traces."""
        C = wp.transpose(F) * F
        J = wp.determinant(F)
        I1 = wp.trace(C)
        trC2 = wp.trace(C * C)
        if wp.static(dim == 2):
            I1 = I1 + scalar(1.0)
            trC2 = trC2 + scalar(1.0)
        return J, I1, trC2

    # Each law adds its isochoric part to the volumetric P (or W) it is given. Arguments: F, G, prm, then
    # I1, tr(C^2), F^-T, J^(-2/3) and dI1b/dF (stress) or I1, tr(C^2), J^(-2/3) and e = I1b - 3 (energy).

    @wp.func
    def neo_hookean_stress(P: mat, F: mat, G: scalar, prm: v3, I1: scalar, trC2: scalar, FinvT: mat, Jm23: scalar, dI1b: mat):
        """P = G J^(-2/3) (F - I1/3 F^-T) + ... (seed 000 eq 10; its extracted text reads F^-2 in the last
        term, F^-T is what the energy gives)."""
        return P + scalar(0.5) * G * dI1b

    @wp.func
    def neo_hookean_energy(W: scalar, G: scalar, prm: v3, I1: scalar, trC2: scalar, Jm23: scalar, e: scalar):
        return W + scalar(0.5) * G * e

    @wp.func
    def mooney_rivlin_stress(P: mat, F: mat, G: scalar, prm: v3, I1: scalar, trC2: scalar, FinvT: mat, Jm23: scalar, dI1b: mat):
        I2 = scalar(0.5) * (I1 * I1 - trC2)
        FC = F * (wp.transpose(F) * F)
        dI2b = Jm23 * Jm23 * (scalar(2.0) * (I1 * F - FC) - (scalar(4.0) / scalar(3.0)) * I2 * FinvT)
        return P + prm[0] * dI1b + prm[1] * dI2b

    @wp.func
    def mooney_rivlin_energy(W: scalar, G: scalar, prm: v3, I1: scalar, trC2: scalar, Jm23: scalar, e: scalar):
        I2 = scalar(0.5) * (I1 * I1 - trC2)
        return W + prm[0] * e + prm[1] * (Jm23 * Jm23 * I2 - scalar(3.0))

    @wp.func
    def yeoh_stress(P: mat, F: mat, G: scalar, prm: v3, I1: scalar, trC2: scalar, FinvT: mat, Jm23: scalar, dI1b: mat):
        e = Jm23 * I1 - scalar(3.0)
        return P + (prm[0] + scalar(2.0) * prm[1] * e + scalar(3.0) * prm[2] * e * e) * dI1b

    @wp.func
    def yeoh_energy(W: scalar, G: scalar, prm: v3, I1: scalar, trC2: scalar, Jm23: scalar, e: scalar):
        return W + prm[0] * e + prm[1] * e * e + prm[2] * e * e * e

    functions = {
        "neo-hookean": (neo_hookean_stress, neo_hookean_energy),
        "mooney-rivlin": (mooney_rivlin_stress, mooney_rivlin_energy),
        "yeoh": (yeoh_stress, yeoh_energy),
    }
    if set(functions) != set(LAWS):
        raise RuntimeError(f"material functions {sorted(functions)} do not match the registry {sorted(LAWS)}")
    codes = tuple(law.code for law in LAWS.values())
    stresses = tuple(functions[name][0] for name in LAWS)
    energies = tuple(functions[name][1] for name in LAWS)

    @wp.func
    def elastic_stress(F: mat, model: int, G: scalar, K: scalar, prm: v3):
        """First Piola stress of law ``model``: volumetric K J (J - 1) F^-T plus the law's isochoric part."""
        J, I1, trC2 = invariants(F)
        FinvT = wp.transpose(wp.inverse(F))
        Jm23 = wp.pow(J, scalar(minus_two_thirds))
        dI1b = Jm23 * (scalar(2.0) * F - (scalar(2.0) / scalar(3.0)) * I1 * FinvT)  # dI1b/dF
        P = K * J * (J - scalar(1.0)) * FinvT
        for i in range(wp.static(len(codes))):
            if model == wp.static(codes[i]):
                P = wp.static(stresses[i])(P, F, G, prm, I1, trC2, FinvT, Jm23, dI1b)
        return P

    @wp.func
    def elastic_energy(F: mat, model: int, G: scalar, K: scalar, prm: v3):
        """Strain energy density per reference volume matching :func:`elastic_stress`."""
        J, I1, trC2 = invariants(F)
        Jm23 = wp.pow(J, scalar(minus_two_thirds))
        e = Jm23 * I1 - scalar(3.0)
        W = scalar(0.5) * K * (J - scalar(1.0)) * (J - scalar(1.0))
        for i in range(wp.static(len(codes))):
            if model == wp.static(codes[i]):
                W = wp.static(energies[i])(W, G, prm, I1, trC2, Jm23, e)
        return W

    return dict(elastic_stress=elastic_stress, elastic_energy=elastic_energy, invariants=invariants, laws=functions)
