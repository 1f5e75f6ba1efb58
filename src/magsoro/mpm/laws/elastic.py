"""Constitutive laws of the MPM engine: a registry with one entry per law, and their Warp functions.

Every law is a compressible hyperelastic solid W(F) = W_iso + K/2 (J - 1)^2 with J = det F, C = F^T F,
I1 = tr C, I2 = (I1^2 - tr C^2) / 2 and the isochoric invariants I1b = J^(-2/3) I1, I2b = J^(-4/3) I2
(2D: plane strain, F_zz = 1, or plane stress with F_zz solved per particle from a zero normal stress,
:func:`make_plane_stress_functions`); the isochoric invariants separate the deviatoric and volumetric responses, as in
the incompressible fits of seed 001. The kinematics and the volumetric part are shared; a law supplies W_iso.
Units: moduli and parameters in Pa, W in J/m^3 of reference volume, first Piola stress P = dW/dF in Pa.

Each particle carries its law's ``code``, its initial shear modulus G (Pa: the Neo-Hookean modulus; for every
law it sets the time step), its bulk modulus K (Pa, default 20 G) and ``LAW_PARAM_COUNT`` (6) law numbers ``prm``
(moduli in Pa, Ogden exponents dimensionless; unused ones 0), packed by :meth:`MaterialLaw.pack` from the scene keys.
A parameter is a number or, with ``terms`` > 0, a list of 1 .. ``terms`` numbers (the Ogden ``mu`` and ``alpha``).

The laws (initial shear modulus in brackets):

- neo-hookean: G/2 (I1b - 3) [G];
- mooney-rivlin: C10 (I1b - 3) + C01 (I2b - 3) [2 (C10 + C01)];
- yeoh: C10 (I1b - 3) + C20 (I1b - 3)^2 + C30 (I1b - 3)^3 [2 C10];
- ogden: sum_i 2 mu_i / alpha_i^2 (lb1^alpha_i + lb2^alpha_i + lb3^alpha_i - 3), i = 1 .. 3, on the isochoric
  principal stretches lb_k = J^(-1/3) lam_k [sum_i mu_i]: Abaqus's form, the ``ogden3`` of ``magsoro fit-material``
  (one term with alpha = 2 is Neo-Hookean with G = mu). Its stress is evaluated in the principal frame of C:
  S = sum_k (1/lam_k dW/dlam_k) N_k N_k^T, P = F S (an isotropic function, so any orthonormal eigenbasis gives
  the same S when stretches repeat);
- polynomial: sum_{1 <= i + j <= 2} Cij (I1b - 3)^i (I2b - 3)^j with C10, C01, C20, C11, C02 [2 (C10 + C01)]:
  the ``polynomial5`` of ``magsoro fit-material``.

``magsoro fit-material`` entries map onto these laws by :data:`FIT_MODEL_LAWS`; its ``linear`` fit (P = E strain,
no strain energy) is read as Neo-Hookean with the same initial shear modulus G = E/3 (equal at small strain only).

Adding a law:

1. An entry in ``LAWS`` below: scene name, the next free code, its parameters (scene key, unit, a typical
   value for the tests), which of them fill the ``LAW_PARAM_COUNT`` engine numbers, its initial shear modulus
   (the small-strain slope of shear stress, Pa) and the condition on the parameters that keeps that modulus > 0.
2. Its two Warp functions in :func:`make_material_functions`, ``<law>_stress`` and ``<law>_energy``, with the
   signatures of the existing ones, listed in the ``functions`` table there. Compute constants in Python
   (double) outside the functions: literal arithmetic inside a Warp function runs in float32.
3. A new parameter key also needs its field in ``Material`` (scene/schema.py); name the law in that class's
   docstring and regenerate docs/scenes.md (``magsoro docs scenes --out docs/scenes.md``), which lists the
   model names.

tests/test_material_registry.py then checks every entry: stress = dW/dF, its initial shear modulus, the schema.
"""

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from numbers import Real

LAW_PARAM_COUNT = 6
"""Law numbers per particle (the ``prm`` vector of the kernels): enough for three Ogden terms (mu_i, alpha_i) or
the five polynomial coefficients; a law's unused slots are 0."""


@dataclass(frozen=True)
class Parameter:
    """A scene key of a law (a field of the scene's Material table).

    ``terms`` = 0: one number; ``terms`` = n > 0: a list of 1 .. n numbers, one per term of the law (the Ogden
    ``mu`` and ``alpha``); its ``example`` is then a tuple."""

    key: str
    unit: str  # "Pa", or "1" for a dimensionless number
    description: str
    example: float | tuple[float, ...]  # a typical value, used by the tests
    required: bool = True  # an inline scene table must give it
    default: float | None = None  # value when a material file lacks it; None: it must be there
    terms: int = 0


def _is_number(x) -> bool:
    return isinstance(x, Real) and not isinstance(x, bool)


@dataclass(frozen=True)
class MaterialLaw:
    """One constitutive law: its scene name, engine code and parameters.

    ``engine_params`` names what fills each of the ``LAW_PARAM_COUNT`` engine numbers: a parameter key, (key, i)
    for term i of a list parameter (0 when the list is shorter), or None (0).
    ``shear`` gives the initial shear modulus (Pa) from the parameters (floats, tuples of floats for list
    parameters); ``constraint`` states the condition on the parameters equivalent to it being > 0. ``check``
    returns a one-line message naming the key for any other bad combination (None when fine). ``read_fit`` turns
    a `magsoro fit-material` entry into scene keys when its [parameters] are not already the law's keys.
    """

    name: str
    code: int
    title: str
    description: str
    parameters: tuple[Parameter, ...]
    engine_params: tuple[str | tuple[str, int] | None, ...]
    shear: Callable[[dict], float]
    constraint: str
    read_fit: Callable[[dict], dict] | None = None
    check: Callable[[dict], str | None] | None = None

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(p.key for p in self.parameters)

    @property
    def required(self) -> tuple[str, ...]:
        return tuple(p.key for p in self.parameters if p.required)

    def values(self, given: Mapping) -> dict[str, float | tuple[float, ...]]:
        """The law's parameters as floats (a tuple of floats for a list parameter), defaults for those ``given``
        lacks; KeyError names a missing one."""
        out = {}
        for p in self.parameters:
            v = given[p.key] if p.key in given or p.default is None else p.default
            out[p.key] = tuple(float(x) for x in v) if p.terms else float(v)
        return out

    def problem(self, given: Mapping) -> str | None:
        """The first thing wrong with the parameters in ``given`` (a one-line message naming the key), or None:
        a list parameter that is not a list of 1 .. terms numbers, a non-finite number, then the law's ``check``.
        Missing keys are not reported here (see :meth:`values`)."""
        for p in self.parameters:
            if p.key not in given:
                continue
            v = given[p.key]
            if p.terms:
                if isinstance(v, (str, bytes)) or not isinstance(v, Sequence) or not 1 <= len(v) <= p.terms:
                    got = f"{len(v)} numbers" if isinstance(v, Sequence) and not isinstance(v, (str, bytes)) else repr(v)
                    return f"{p.key} must be a list of 1 to {p.terms} numbers (one per term), got {got}"
                items = list(v)
            else:
                items = [v]
            if not all(_is_number(x) and math.isfinite(x) for x in items):
                return f"{p.key} must be {'finite numbers' if p.terms else 'a finite number'}, got {v!r}"
        if self.check is None:
            return None
        try:
            values = self.values(given)
        except KeyError:
            return None
        return self.check(values)

    def initial_shear_modulus(self, given: Mapping) -> float:
        """Small-strain shear modulus, Pa."""
        return self.shear(self.values(given))

    def pack(self, given: Mapping) -> tuple[float, ...]:
        """The ``LAW_PARAM_COUNT`` engine numbers of the particles' ``material_params`` (unused ones 0)."""
        v = self.values(given)

        def slot(s):
            if s is None:
                return 0.0
            if isinstance(s, tuple):
                key, i = s
                return v[key][i] if i < len(v[key]) else 0.0
            return v[s]

        return tuple(slot(s) for s in self.engine_params)

    def from_material_file(self, entry: dict) -> dict:
        """Scene keys of this law from a `magsoro fit-material` entry."""
        if self.read_fit is not None:
            return self.read_fit(entry)
        params = entry.get("parameters", {})
        return {k: params[k] for k in self.keys if k in params}


def _neo_hookean_from_fit(entry: dict) -> dict:
    # the fit writes W = C10 (I1 - 3), so G = 2 C10; a linear fit P = E strain has G = E/3 (incompressible, small
    # strain); otherwise the entry's initial shear modulus
    params = entry.get("parameters", {})
    if "C10" in params:
        return {"shear_modulus": 2.0 * params["C10"]}
    if "E" in params:
        return {"shear_modulus": params["E"] / 3.0}
    return {"shear_modulus": entry.get("shear_modulus")}


def _ogden_from_fit(entry: dict) -> dict:
    # the fit writes mu1, alpha1, mu2, alpha2, ... (every term, also one with mu_i = 0); an entry may also give
    # the scene's lists mu and alpha
    params = entry.get("parameters", {})
    if "mu" in params or "alpha" in params:
        return {k: params[k] for k in ("mu", "alpha") if k in params}
    n = 0
    while f"mu{n + 1}" in params or f"alpha{n + 1}" in params:
        n += 1
    for i in range(1, n + 1):
        for k in (f"mu{i}", f"alpha{i}"):
            if k not in params:
                raise KeyError(k)
    return {"mu": [params[f"mu{i}"] for i in range(1, n + 1)], "alpha": [params[f"alpha{i}"] for i in range(1, n + 1)]}


def _ogden_check(p: dict) -> str | None:
    mu, alpha = p["mu"], p["alpha"]
    if len(mu) != len(alpha):
        return f"mu and alpha must have the same length (one pair per Ogden term), got {len(mu)} and {len(alpha)}"
    if any(a == 0.0 for a in alpha):
        return f"alpha must be non-zero (an Ogden term with alpha = 0 is undefined), got {list(alpha)}"
    return None


def _registry(*laws: MaterialLaw) -> dict[str, MaterialLaw]:
    out = {law.name: law for law in laws}
    if len(out) != len(laws) or sorted(law.code for law in laws) != list(range(len(laws))):
        raise ValueError("material laws need distinct names and codes 0 .. n-1")
    for law in laws:
        terms = {p.key: p.terms for p in law.parameters}
        ok = len(law.engine_params) == LAW_PARAM_COUNT
        for s in law.engine_params:
            if isinstance(s, tuple):
                ok = ok and len(s) == 2 and terms.get(s[0], 0) > s[1] >= 0
            elif s is not None:
                ok = ok and s in terms and terms[s] == 0
        if not ok:
            raise ValueError(f"{law.name}: engine_params must be {LAW_PARAM_COUNT} of its parameter keys, (list key, "
                             "term) pairs or None")
    return out


LAWS: dict[str, MaterialLaw] = _registry(
    MaterialLaw(
        name="neo-hookean",
        code=0,
        title="Neo-Hookean",
        description="W = G/2 (I1b - 3) (seed 000 eq 10)",
        parameters=(Parameter("shear_modulus", "Pa", "shear modulus G", 3.0e5),),
        engine_params=(None,) * LAW_PARAM_COUNT,  # the engine reads G from the particle's shear modulus
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
        engine_params=("C10", "C01", None, None, None, None),
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
        engine_params=("C10", "C20", "C30", None, None, None),
        shear=lambda p: 2.0 * p["C10"],
        constraint="C10 > 0",
    ),
    MaterialLaw(
        name="ogden",
        code=3,
        title="Ogden",
        description="W = sum_i 2 mu_i / alpha_i^2 (lb1^alpha_i + lb2^alpha_i + lb3^alpha_i - 3), i = 1 .. 3, on the "
                    "isochoric principal stretches lb_k = J^(-1/3) lam_k (Abaqus's form, fit-material's ogden3); "
                    "initial shear modulus sum_i mu_i",
        parameters=(
            Parameter("mu", "Pa", "Ogden moduli mu_i", (1.2e5, 3.0e3, -2.0e3), terms=3),
            Parameter("alpha", "1", "Ogden exponents alpha_i (non-zero)", (1.3, 5.0, -2.0), terms=3),
        ),
        engine_params=(("mu", 0), ("alpha", 0), ("mu", 1), ("alpha", 1), ("mu", 2), ("alpha", 2)),
        shear=lambda p: math.fsum(p["mu"]),
        constraint="sum(mu) > 0",
        read_fit=_ogden_from_fit,
        check=_ogden_check,
    ),
    MaterialLaw(
        name="polynomial",
        code=4,
        title="polynomial",
        description="W = sum_{1 <= i + j <= 2} Cij (I1b - 3)^i (I2b - 3)^j (fit-material's polynomial5); initial "
                    "shear modulus 2 (C10 + C01)",
        parameters=(
            Parameter("C10", "Pa", "coefficient of (I1b - 3)", 1.1e5),
            Parameter("C01", "Pa", "coefficient of (I2b - 3)", 0.3e5, required=False, default=0.0),
            Parameter("C20", "Pa", "coefficient of (I1b - 3)^2", -2.0e3, required=False, default=0.0),
            Parameter("C11", "Pa", "coefficient of (I1b - 3)(I2b - 3)", 1.0e3, required=False, default=0.0),
            Parameter("C02", "Pa", "coefficient of (I2b - 3)^2", 5.0e2, required=False, default=0.0),
        ),
        engine_params=("C10", "C01", "C20", "C11", "C02", None),
        shear=lambda p: 2.0 * (p["C10"] + p["C01"]),
        constraint="C10 + C01 > 0",
    ),
)

DEFAULT_LAW = "neo-hookean"  # also the law of material library entries (they give a shear modulus)
LAW_NAMES = tuple(LAWS)
# every parameter key of every law, in registry order
PARAMETER_KEYS = tuple(dict.fromkeys(k for law in LAWS.values() for k in law.keys))
# the list-valued keys (Parameter.terms > 0) and their most terms
LIST_KEYS = {p.key: p.terms for law in LAWS.values() for p in law.parameters if p.terms}

FIT_MODEL_LAWS = {
    "linear": "neo-hookean",  # P = E strain has no strain energy: Neo-Hookean with G = E/3, equal at small strain
    "neo-hookean": "neo-hookean",
    "mooney-rivlin": "mooney-rivlin",
    "yeoh": "yeoh",
    "ogden3": "ogden",
    "polynomial5": "polynomial",
}
"""The engine law of each `magsoro fit-material` model (magsoro.characterization.hyperelastic.MODEL_NAMES)."""


def law_of_file_model(model) -> str | None:
    """The law name for a material file's ``model`` (a fit-material model or a law name), or None."""
    if not isinstance(model, str):
        return None
    name = FIT_MODEL_LAWS.get(model, model)
    return name if name in LAWS else None


def describe_codes() -> str:
    """'0 (Neo-Hookean), 1 (Mooney-Rivlin), ... or 4 (polynomial)'."""
    items = [f"{law.code} ({law.title})" for law in sorted(LAWS.values(), key=lambda law: law.code)]
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " or " + items[-1]


@functools.cache
def make_material_functions(dim: int, scalar):
    """Warp functions ``elastic_stress(F, model, G, K, prm)`` (first Piola stress, Pa) and ``elastic_energy``
    (same arguments; J/m^3) for ``dim`` in (2, 3) and ``scalar`` in (wp.float32, wp.float64), dispatching on the
    law code ``model``; ``prm`` is a vector of ``LAW_PARAM_COUNT`` law numbers. Also ``invariants``,
    ``principal_stretches`` and, per law name, its (stress, energy) pair."""
    import warp as wp

    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim}")
    mat = wp.types.matrix(shape=(dim, dim), dtype=scalar)
    vprm = wp.types.vector(length=LAW_PARAM_COUNT, dtype=scalar)
    vdim = wp.types.vector(length=dim, dtype=scalar)
    # Constants are computed here in double precision: literal arithmetic inside a Warp function runs in float32.
    minus_two_thirds = -2.0 / 3.0
    one_third = 1.0 / 3.0
    four_thirds = 4.0 / 3.0
    # float32: a second Jacobi pass of wp.eig3 (4 sweeps) on the nearly diagonal Q^T C Q; one pass left relative
    # errors |Q diag(d) Q^T - C| / |C| up to 1.5e-3 at stretches of a few, two stay below 1e-5. float64 runs 8
    # sweeps (2e-14 in one pass).
    polish = scalar == wp.float32

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

    if dim == 3:

        @wp.func
        def principal_stretches(F: mat):
            """Eigenvalues d (squared principal stretches lam_k^2) of C = F^T F and a matrix Q whose columns are
            orthonormal eigenvectors N_k: C = Q diag(d) Q^T (any orthonormal basis of a repeated eigenvalue).
            The smallest eigenvalue is taken as det C / (product of the other two) = J^2 / (d_i d_j): its error
            from the decomposition is eps |C|, large relative to it when the stretches differ a lot (float32, one
            Ogden term alpha = 2 at stretches 7.0, 4.0, 0.053: 0.7 % of the stress from eig3's value, 0.01 % so)."""
            C = wp.transpose(F) * F
            Q, d = wp.eig3(C)
            if wp.static(polish):
                Q2, dp = wp.eig3(wp.transpose(Q) * C * Q)
                Q = Q * Q2
                d = dp
            J = wp.determinant(F)
            a = d[0]
            b = d[1]
            c = d[2]
            if a <= b and a <= c:
                a = J * J / (b * c)
            elif b <= c:
                b = J * J / (a * c)
            else:
                c = J * J / (a * b)
            return Q, vdim(a, b, c)

    else:

        @wp.func
        def principal_stretches(F: mat):
            """In-plane eigenvalues d (lam_1^2 >= lam_2^2) of C = F^T F and the in-plane difference of the
            eigenprojections N1 N1^T - N2 N2^T = [[c, s], [s, -c]] (c, s = cos, sin of twice the angle of N1), in
            closed form; with equal eigenvalues any basis does and (c, s) = (1, 0). lam_3 = 1 (plane strain)."""
            C = wp.transpose(F) * F
            h = scalar(0.5) * (C[0, 0] - C[1, 1])
            b = C[0, 1]
            q = h * h + b * b
            r = scalar(0.0)
            c = scalar(1.0)
            s = scalar(0.0)
            if q > scalar(0.0):
                r = wp.sqrt(q)
                c = h / r
                s = b / r
            d1 = scalar(0.5) * (C[0, 0] + C[1, 1]) + r
            J = wp.determinant(F)
            d2 = J * J / d1  # det C / d1: no cancellation when lam_2 << lam_1
            return vdim(d1, d2), c, s

    # Each law adds its isochoric part to the volumetric P (or W) it is given. Arguments: F, G, prm, then
    # I1, tr(C^2), F^-T, J^(-2/3) and dI1b/dF (stress) or F, G, prm, I1, tr(C^2), J^(-2/3) and e = I1b - 3 (energy).

    @wp.func
    def neo_hookean_stress(P: mat, F: mat, G: scalar, prm: vprm, I1: scalar, trC2: scalar, FinvT: mat, Jm23: scalar, dI1b: mat):
        """P = G J^(-2/3) (F - I1/3 F^-T) + ... (seed 000 eq 10; its extracted text reads F^-2 in the last
        term, F^-T is what the energy gives)."""
        return P + scalar(0.5) * G * dI1b

    @wp.func
    def neo_hookean_energy(W: scalar, F: mat, G: scalar, prm: vprm, I1: scalar, trC2: scalar, Jm23: scalar, e: scalar):
        return W + scalar(0.5) * G * e

    @wp.func
    def mooney_rivlin_stress(P: mat, F: mat, G: scalar, prm: vprm, I1: scalar, trC2: scalar, FinvT: mat, Jm23: scalar, dI1b: mat):
        I2 = scalar(0.5) * (I1 * I1 - trC2)
        FC = F * (wp.transpose(F) * F)
        dI2b = Jm23 * Jm23 * (scalar(2.0) * (I1 * F - FC) - (scalar(4.0) / scalar(3.0)) * I2 * FinvT)
        return P + prm[0] * dI1b + prm[1] * dI2b

    @wp.func
    def mooney_rivlin_energy(W: scalar, F: mat, G: scalar, prm: vprm, I1: scalar, trC2: scalar, Jm23: scalar, e: scalar):
        I2 = scalar(0.5) * (I1 * I1 - trC2)
        return W + prm[0] * e + prm[1] * (Jm23 * Jm23 * I2 - scalar(3.0))

    @wp.func
    def yeoh_stress(P: mat, F: mat, G: scalar, prm: vprm, I1: scalar, trC2: scalar, FinvT: mat, Jm23: scalar, dI1b: mat):
        e = Jm23 * I1 - scalar(3.0)
        return P + (prm[0] + scalar(2.0) * prm[1] * e + scalar(3.0) * prm[2] * e * e) * dI1b

    @wp.func
    def yeoh_energy(W: scalar, F: mat, G: scalar, prm: vprm, I1: scalar, trC2: scalar, Jm23: scalar, e: scalar):
        return W + prm[0] * e + prm[1] * e * e + prm[2] * e * e * e

    @wp.func
    def ogden_terms(l1: scalar, l2: scalar, l3: scalar, prm: vprm):
        """At isochoric principal stretches l1, l2, l3: the principal Kirchhoff stresses tau_k = lam_k dW_iso/dlam_k
        = sum_i (2 mu_i / alpha_i) (lb_k^alpha_i - (lb1^alpha_i + lb2^alpha_i + lb3^alpha_i) / 3) and W_iso.
        prm = (mu1, alpha1, mu2, alpha2, mu3, alpha3); a term with alpha = 0 is unused (its mu is 0)."""
        t1 = scalar(0.0)
        t2 = scalar(0.0)
        t3 = scalar(0.0)
        W = scalar(0.0)
        for i in range(3):
            a = prm[2 * i + 1]
            if a != scalar(0.0):
                ca = scalar(2.0) * prm[2 * i] / a
                p1 = wp.pow(l1, a)
                p2 = wp.pow(l2, a)
                p3 = wp.pow(l3, a)
                mean = (p1 + p2 + p3) * scalar(one_third)
                t1 = t1 + ca * (p1 - mean)
                t2 = t2 + ca * (p2 - mean)
                t3 = t3 + ca * (p3 - mean)
                W = W + ca / a * (p1 + p2 + p3 - scalar(3.0))
        return t1, t2, t3, W

    if dim == 3:

        @wp.func
        def ogden_stress(P: mat, F: mat, G: scalar, prm: vprm, I1: scalar, trC2: scalar, FinvT: mat, Jm23: scalar, dI1b: mat):
            """P = F S, S = sum_k tau_k / lam_k^2 N_k N_k^T in the principal frame of C."""
            Q, d = principal_stretches(F)
            Jm13 = wp.sqrt(Jm23)
            t1, t2, t3, W = ogden_terms(Jm13 * wp.sqrt(d[0]), Jm13 * wp.sqrt(d[1]), Jm13 * wp.sqrt(d[2]), prm)
            S = Q * wp.diag(vdim(t1 / d[0], t2 / d[1], t3 / d[2])) * wp.transpose(Q)
            return P + F * S

        @wp.func
        def ogden_energy(W: scalar, F: mat, G: scalar, prm: vprm, I1: scalar, trC2: scalar, Jm23: scalar, e: scalar):
            Q, d = principal_stretches(F)
            Jm13 = wp.sqrt(Jm23)
            t1, t2, t3, Wi = ogden_terms(Jm13 * wp.sqrt(d[0]), Jm13 * wp.sqrt(d[1]), Jm13 * wp.sqrt(d[2]), prm)
            return W + Wi

    else:

        @wp.func
        def ogden_stress(P: mat, F: mat, G: scalar, prm: vprm, I1: scalar, trC2: scalar, FinvT: mat, Jm23: scalar, dI1b: mat):
            """P = F S, S = sum_k tau_k / lam_k^2 N_k N_k^T over the in-plane principal directions (lam_3 = 1)."""
            d, c, s = principal_stretches(F)
            Jm13 = wp.sqrt(Jm23)
            t1, t2, t3, W = ogden_terms(Jm13 * wp.sqrt(d[0]), Jm13 * wp.sqrt(d[1]), Jm13, prm)
            s1 = t1 / d[0]
            s2 = t2 / d[1]
            mean = scalar(0.5) * (s1 + s2)
            half = scalar(0.5) * (s1 - s2)
            S = mat(mean + half * c, half * s, half * s, mean - half * c)
            return P + F * S

        @wp.func
        def ogden_energy(W: scalar, F: mat, G: scalar, prm: vprm, I1: scalar, trC2: scalar, Jm23: scalar, e: scalar):
            d, c, s = principal_stretches(F)
            Jm13 = wp.sqrt(Jm23)
            t1, t2, t3, Wi = ogden_terms(Jm13 * wp.sqrt(d[0]), Jm13 * wp.sqrt(d[1]), Jm13, prm)
            return W + Wi

    @wp.func
    def polynomial_stress(P: mat, F: mat, G: scalar, prm: vprm, I1: scalar, trC2: scalar, FinvT: mat, Jm23: scalar, dI1b: mat):
        """prm = (C10, C01, C20, C11, C02, 0): dW/dI1b dI1b/dF + dW/dI2b dI2b/dF."""
        I2 = scalar(0.5) * (I1 * I1 - trC2)
        e1 = Jm23 * I1 - scalar(3.0)
        e2 = Jm23 * Jm23 * I2 - scalar(3.0)
        FC = F * (wp.transpose(F) * F)
        dI2b = Jm23 * Jm23 * (scalar(2.0) * (I1 * F - FC) - scalar(four_thirds) * I2 * FinvT)
        W1 = prm[0] + scalar(2.0) * prm[2] * e1 + prm[3] * e2
        W2 = prm[1] + prm[3] * e1 + scalar(2.0) * prm[4] * e2
        return P + W1 * dI1b + W2 * dI2b

    @wp.func
    def polynomial_energy(W: scalar, F: mat, G: scalar, prm: vprm, I1: scalar, trC2: scalar, Jm23: scalar, e: scalar):
        I2 = scalar(0.5) * (I1 * I1 - trC2)
        e2 = Jm23 * Jm23 * I2 - scalar(3.0)
        return W + prm[0] * e + prm[1] * e2 + prm[2] * e * e + prm[3] * e * e2 + prm[4] * e2 * e2

    functions = {
        "neo-hookean": (neo_hookean_stress, neo_hookean_energy),
        "mooney-rivlin": (mooney_rivlin_stress, mooney_rivlin_energy),
        "yeoh": (yeoh_stress, yeoh_energy),
        "ogden": (ogden_stress, ogden_energy),
        "polynomial": (polynomial_stress, polynomial_energy),
    }
    if set(functions) != set(LAWS):
        raise RuntimeError(f"material functions {sorted(functions)} do not match the registry {sorted(LAWS)}")
    codes = tuple(law.code for law in LAWS.values())
    stresses = tuple(functions[name][0] for name in LAWS)
    energies = tuple(functions[name][1] for name in LAWS)

    @wp.func
    def elastic_stress(F: mat, model: int, G: scalar, K: scalar, prm: vprm):
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
    def elastic_energy(F: mat, model: int, G: scalar, K: scalar, prm: vprm):
        """Strain energy density per reference volume matching :func:`elastic_stress`."""
        J, I1, trC2 = invariants(F)
        Jm23 = wp.pow(J, scalar(minus_two_thirds))
        e = Jm23 * I1 - scalar(3.0)
        W = scalar(0.5) * K * (J - scalar(1.0)) * (J - scalar(1.0))
        for i in range(wp.static(len(codes))):
            if model == wp.static(codes[i]):
                W = wp.static(energies[i])(W, F, G, prm, I1, trC2, Jm23, e)
        return W

    return dict(elastic_stress=elastic_stress, elastic_energy=elastic_energy, invariants=invariants,
                principal_stretches=principal_stretches, laws=functions)


#: most secant iterations of the plane-stress thickness stretch (a dynamic loop: it stops when converged, in a few
#: iterations from the incompressible guess at the strains of the scenes)
PLANE_STRESS_ITERATIONS = 20


@functools.cache
def make_plane_stress_functions(scalar) -> dict:
    """The 2D plane-stress form of every law (docs/engine.md, "Plane stress"): the law is evaluated in 3D at
    F = diag(F_2D, lam_3), with the out-of-plane stretch lam_3 solved from a zero normal stress P_33 = 0 by the
    secant method from the incompressible guess det(F_2D)^(-1/2), its first step by the small-strain slope
    K + 4G/3 (one law evaluation per iteration: every call inlines all the laws, and CUDA's compiler pays for the
    generated code's size). The in-plane
    block of that 3D stress is dW/dF_2D of the reduced energy W(F_2D, lam_3(F_2D)) (P_33 = 0 removes the lam_3
    term), so stress and energy stay a consistent pair and the static solver's central-difference tangent of
    P(F_2D) is the consistent plane-stress tangent. Same signatures as :func:`make_material_functions`:

    - ``plane_stress_stretch(F, model, G, K, prm)``: lam_3;
    - ``plane_stress_stress`` / ``plane_stress_energy(F, model, G, K, prm)``: P (2 x 2, Pa) and W (J/m^3 of
      reference volume)."""
    import warp as wp

    mat = wp.types.matrix(shape=(2, 2), dtype=scalar)
    vprm = wp.types.vector(length=LAW_PARAM_COUNT, dtype=scalar)
    m3 = wp.types.matrix(shape=(3, 3), dtype=scalar)
    f3 = make_material_functions(3, scalar)
    stress3, energy3 = f3["elastic_stress"], f3["elastic_energy"]
    double = scalar == wp.float64
    # converged when |P_33| <= tol (K + G): just above the rounding of P_33 (float64 ~1e-16, float32 ~1e-7 of K),
    # since the static solver's central-difference tangent sees what is left (at 1e-13 in float64 a pre-buckled
    # arch's stability check found a spurious negative eigenvalue and switched branch); a secant step that no
    # longer moves lam_3 also ends the loop
    tol = 1.0e-15 if double else 2.0e-6
    iterations = PLANE_STRESS_ITERATIONS
    four_thirds = 4.0 / 3.0

    @wp.func
    def thick(F: mat, l3: scalar):
        """diag(F, l3) as a 3 x 3 deformation gradient."""
        z = scalar(0.0)
        return m3(F[0, 0], F[0, 1], z, F[1, 0], F[1, 1], z, z, z, l3)

    @wp.func
    def normal_stress(F: mat, l3: scalar, model: int, G: scalar, K: scalar, prm: vprm):
        P = stress3(thick(F, l3), model, G, K, prm)
        return P[2, 2]

    @wp.func
    def plane_stress_stretch(F: mat, model: int, G: scalar, K: scalar, prm: vprm):
        """Out-of-plane stretch lam_3 with P_33(diag(F, lam_3)) = 0 (:func:`thickness_secant`)."""
        J = wp.determinant(F)
        l0 = scalar(1.0)
        if J > scalar(0.0):
            l0 = scalar(1.0) / wp.sqrt(J)
        r0 = normal_stress(F, l0, model, G, K, prm)
        slope0 = K + scalar(four_thirds) * G
        l1 = wp.clamp(l0 - r0 / slope0, scalar(0.5) * l0, scalar(2.0) * l0)
        it = int(0)
        while it < iterations:
            r1 = normal_stress(F, l1, model, G, K, prm)
            if wp.abs(r1) <= scalar(tol) * (K + G) or l1 == l0:
                break
            slope = (r1 - r0) / (l1 - l0)
            if slope <= scalar(0.0):  # not expected of a stable law: step by the small-strain slope
                slope = slope0
            l0 = l1
            r0 = r1
            l1 = wp.clamp(l1 - r1 / slope, scalar(0.5) * l1, scalar(2.0) * l1)
            it += 1
        return l1

    @wp.func
    def plane_stress_stress(F: mat, model: int, G: scalar, K: scalar, prm: vprm):
        l3 = plane_stress_stretch(F, model, G, K, prm)
        P = stress3(thick(F, l3), model, G, K, prm)
        return mat(P[0, 0], P[0, 1], P[1, 0], P[1, 1])

    @wp.func
    def plane_stress_energy(F: mat, model: int, G: scalar, K: scalar, prm: vprm):
        l3 = plane_stress_stretch(F, model, G, K, prm)
        return energy3(thick(F, l3), model, G, K, prm)

    return dict(plane_stress_stretch=plane_stress_stretch, plane_stress_stress=plane_stress_stress,
                plane_stress_energy=plane_stress_energy)
