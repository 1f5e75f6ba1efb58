"""Design variables: map a flat parameter vector onto the rollout's inputs and the rollout's gradients back.

Variable kinds (``--vars`` names):

- ``magnetisation``: one remanence vector Br (T, 3 components) per magnetised body (or per listed body); the
  body becomes uniformly magnetised with it.
- ``magnetisation_particles``: Br (T) of every particle of those bodies (written back as an array file).
- ``field``: the vector B (T) of every ``uniform`` field (with its ramp / sine profile kept), i.e. its
  magnitude and direction.
- ``keyframes``: the field vectors (T) at the keyframes of every ``keyframes`` field (its time profile).
- ``epm``: position (m) and moment (A m^2) of every ``dipole`` field without a path (the magnet's pose).
- ``material``: the shear modulus G (Pa) of every Neo-Hookean body (or of the listed bodies); the bulk modulus
  keeps its ratio to G.
"""

import numpy as np

from magsoro.errors import MagsoroError
from magsoro.fields import Keyframes
from magsoro.scene.build import make_field

KINDS = ("magnetisation", "magnetisation_particles", "field", "keyframes", "epm", "material")


class Variable:
    """One block of the design vector: ``name``, ``kind``, ``value`` (physical units), ``scale`` (typical size)."""

    def __init__(self, name, kind, value, scale, **info):
        self.name, self.kind = name, kind
        self.value = np.asarray(value, dtype=np.float64).ravel().copy()
        self.scale = np.broadcast_to(np.asarray(scale, dtype=np.float64), self.value.shape).copy()
        self.info = info


def check_request(kinds, allowed, bodies, body_names, unknown_kind=None) -> None:
    """MagsoroError for variable kinds not in ``allowed`` (``unknown_kind``: the message's template, with {kind}
    and {allowed}), no kind at all, or a body name that is not in ``body_names``."""
    unknown = [k for k in kinds if k not in allowed]
    if unknown:
        template = unknown_kind or "--vars: unknown variable kind '{kind}'; choose from {allowed}"
        raise MagsoroError(template.format(kind=unknown[0], allowed=", ".join(allowed)))
    if not kinds:
        raise MagsoroError("--vars: give at least one variable kind")
    if bodies is not None:
        bad = [b for b in bodies if b not in body_names]
        if bad:
            raise MagsoroError(f"--bodies: no body named '{bad[0]}'; bodies: {', '.join(body_names)}")


def body_variables(kind, host, body_index, chosen, bodies) -> list:
    """The Variables of a body kind: ``magnetisation`` (a mean remanence vector, T, per magnetised body, or per
    listed body when ``bodies`` is given), ``magnetisation_particles`` (every particle's) or ``material`` (the
    shear modulus, Pa, of each Neo-Hookean body; a listed body that is not is an error)."""
    out = []
    Br = host["remanence"]
    if kind in ("magnetisation", "magnetisation_particles"):
        names = [b for b in chosen if bodies is not None or np.any(np.linalg.norm(Br[body_index[b]], axis=1) > 0)]
        if not names:
            raise MagsoroError("magnetisation: no magnetised body; name the bodies to design with --bodies")
        scale = max(float(np.max(np.linalg.norm(Br, axis=1))), 1e-3)
        for b in names:
            idx = body_index[b]
            if kind == "magnetisation":
                out.append(Variable(f"{b}.magnetization", kind, Br[idx].mean(axis=0), scale, body=b))
            else:
                out.append(Variable(f"{b}.magnetization[particles]", kind, Br[idx], scale, body=b))
    elif kind == "material":
        for b in chosen:
            idx = body_index[b]
            if np.any(host["material_model"][idx] != 0):
                if bodies is None:
                    continue
                raise MagsoroError(f"material: body '{b}' is not Neo-Hookean; only its shear modulus G can be designed")
            G = float(host["shear_modulus"][idx].mean())
            out.append(Variable(f"{b}.material.shear_modulus", kind, [G], G, body=b))
    return out


class Design:
    """The design variables of a scene for a :class:`~magsoro.diff.rollout.Rollout`.

    ``kinds``: variable kinds (see module docstring); ``bodies``: restrict body variables to these names.
    ``values()`` / ``apply(values)`` read and set the flat physical vector; ``gradient(grads)`` turns the
    rollout's gradients into dL/d(values).
    """

    def __init__(self, scene, rollout, kinds, bodies=None):
        self.scene, self.rollout = scene, rollout
        built = rollout.built
        self.dim = built.model.dim
        check_request(kinds, KINDS, bodies, built.body_names)
        h = built.model.host
        self.body_index = {name: np.flatnonzero(h["body"] == i) for i, name in enumerate(built.body_names)}
        self.base = {key: h[key].copy() for key in ("remanence", "shear_modulus", "bulk_modulus")}
        self.base_uniform = rollout.B_uniform.numpy().astype(np.float64)
        flat = []
        for s in rollout.control.sources:
            flat.extend(s.sources())
        self.vars: list[Variable] = []
        chosen = bodies if bodies is not None else built.body_names
        for kind in kinds:
            if kind in ("magnetisation", "magnetisation_particles", "material"):
                self.vars.extend(body_variables(kind, h, self.body_index, chosen, bodies))
            elif kind in ("field", "keyframes", "epm"):
                found = False
                for i, spec in enumerate(scene.fields):
                    if kind == "field" and spec.type == "uniform":
                        B = np.asarray(spec.B, dtype=np.float64)
                        unit = make_field(spec.model_copy(update={"B": [1.0, 1.0, 1.0]}), None)
                        s = np.array([unit.uniform_value(t)[0] for t in rollout.times])
                        self.vars.append(Variable(f"fields[{i}].B", kind, B, max(np.linalg.norm(B), 1e-3), field=i, profile=s))
                        found = True
                    elif kind == "keyframes" and spec.type == "keyframes":
                        src = make_field(spec, scene.base_dir)
                        times = src.profile.table.times
                        vals = src.profile.table.values
                        W = np.array([Keyframes(times, np.eye(len(times))).value(t) for t in rollout.times])
                        self.vars.append(Variable(f"fields[{i}].values", kind, vals, max(np.max(np.linalg.norm(vals, axis=1)), 1e-3),
                                                  field=i, weights=W, times=times))
                        found = True
                    elif kind == "epm" and spec.type == "dipole":
                        if spec.path is not None:
                            raise MagsoroError(f"epm: fields[{i}] moves along a path; only a fixed dipole pose can be designed")
                        pos = np.asarray(spec.position, dtype=np.float64)
                        mom = np.asarray(spec.moment, dtype=np.float64)
                        dist = float(np.linalg.norm(pos - np.r_[h["positions"].mean(axis=0), np.zeros(3 - self.dim)]))
                        scale = np.r_[np.full(3, max(dist, 1e-3)), np.full(3, max(np.linalg.norm(mom), 1e-6))]
                        before = sum(1 for f in rollout.control.sources[:i] for e in f.sources() if not e.uniform)
                        self.vars.append(Variable(f"fields[{i}].pose", kind, np.r_[pos, mom], scale, field=i, source=before))
                        found = True
                if not found:
                    need = {"field": "uniform", "keyframes": "keyframes", "epm": "dipole"}[kind]
                    raise MagsoroError(f"{kind}: the scene has no '{need}' field to design")
        self.sizes = [v.value.size for v in self.vars]

    # -- flat vectors ---------------------------------------------------------------------------------------
    def values(self) -> np.ndarray:
        return np.concatenate([v.value for v in self.vars])

    def scales(self) -> np.ndarray:
        return np.concatenate([v.scale for v in self.vars])

    def names(self) -> list[str]:
        out = []
        for v in self.vars:
            out.extend(f"{v.name}[{j}]" for j in range(v.value.size))
        return out

    def _split(self, flat):
        out, i = [], 0
        for n in self.sizes:
            out.append(np.asarray(flat[i : i + n], dtype=np.float64))
            i += n
        return out

    def apply(self, flat) -> None:
        """Set the rollout's inputs from the flat physical vector."""
        ro = self.rollout
        Br = self.base["remanence"].copy()
        G = self.base["shear_modulus"].copy()
        K = self.base["bulk_modulus"].copy()
        Bu = self.base_uniform.copy()
        touched = set()
        for v, val in zip(self.vars, self._split(flat)):
            v.value = val.copy()
            if v.kind == "magnetisation":
                Br[self.body_index[v.info["body"]]] = val
                touched.add("Br")
            elif v.kind == "magnetisation_particles":
                Br[self.body_index[v.info["body"]]] = val.reshape(-1, 3)
                touched.add("Br")
            elif v.kind == "material":
                idx = self.body_index[v.info["body"]]
                ratio = self.base["bulk_modulus"][idx] / self.base["shear_modulus"][idx]
                G[idx] = val[0]
                K[idx] = ratio * val[0]
                touched.add("G")
            elif v.kind == "field":
                src = self.scene.fields[v.info["field"]]
                Bu += np.outer(v.info["profile"], val - np.asarray(src.B, dtype=np.float64))
            elif v.kind == "keyframes":
                orig = np.asarray(make_field(self.scene.fields[v.info["field"]], self.scene.base_dir).profile.table.values)
                Bu += v.info["weights"] @ (val.reshape(-1, 3) - orig)
            elif v.kind == "epm":
                rows = np.tile(val, (ro.n_steps, 1))
                ro.set_source_params(v.info["source"], rows)
        ro.set_particle_arrays(Br=Br if "Br" in touched else None, shear=G if "G" in touched else None, bulk=K if "G" in touched else None)
        if any(v.kind in ("field", "keyframes") for v in self.vars):
            ro.set_uniform_field(Bu)

    def gradient(self, grads) -> np.ndarray:
        """dL/d(values) from the rollout's gradients (chain rule through the variable maps)."""
        out = []
        for v in self.vars:
            if v.kind == "magnetisation":
                out.append(grads["Br"][self.body_index[v.info["body"]]].sum(axis=0))
            elif v.kind == "magnetisation_particles":
                out.append(grads["Br"][self.body_index[v.info["body"]]].ravel())
            elif v.kind == "material":
                idx = self.body_index[v.info["body"]]
                ratio = self.base["bulk_modulus"][idx] / self.base["shear_modulus"][idx]
                out.append(np.array([np.sum(grads["shear"][idx] + ratio * grads["bulk"][idx])]))
            elif v.kind == "field":
                out.append(v.info["profile"] @ grads["B_uniform"])
            elif v.kind == "keyframes":
                out.append((v.info["weights"].T @ grads["B_uniform"]).ravel())
            elif v.kind == "epm":
                out.append(grads["source_params"][v.info["source"]].sum(axis=0)[:6])
        return np.concatenate(out)

    # -- scene write-back -------------------------------------------------------------------------------------
    def write_back(self, raw: dict, out_dir) -> dict:
        """Return a copy of the raw scene table with the current design; per-particle magnetisations are
        written as .npy files into ``out_dir`` and referenced from the scene."""
        import copy
        from pathlib import Path

        data = copy.deepcopy(raw)
        bodies = {}
        for b in data.get("bodies", []):
            bodies[b["name"]] = b
        robot = data.get("robot")
        if isinstance(robot, dict):
            for b in robot.get("parts", []):
                bodies[b["name"]] = b
        X = self.rollout.model.host["positions"]
        for v in self.vars:
            if v.kind in ("magnetisation", "magnetisation_particles", "material"):
                name = v.info["body"]
                if name not in bodies:
                    raise MagsoroError(f"body '{name}' comes from a robot file; inline its part in the scene to write the design back")
                body = bodies[name]
                if v.kind == "magnetisation":
                    body["magnetization"] = [float(c) for c in v.value]
                elif v.kind == "magnetisation_particles":
                    idx = self.body_index[name]
                    pts = np.zeros((len(idx), 3))
                    pts[:, : self.dim] = X[idx]
                    path = Path(out_dir) / f"magnetization_{name}.npy"
                    np.save(path, np.hstack([pts, v.value.reshape(-1, 3)]))
                    body["magnetization"] = {"type": "file", "file": str(path.resolve())}
                else:
                    mat = body["material"]
                    mat = {"library": mat} if isinstance(mat, str) else dict(mat)
                    mat["shear_modulus"] = float(v.value[0])
                    if "bulk_modulus" in mat:
                        idx = self.body_index[name]
                        mat["bulk_modulus"] = float(v.value[0] * self.base["bulk_modulus"][idx][0] / self.base["shear_modulus"][idx][0])
                    body["material"] = mat
            elif v.kind == "field":
                data["fields"][v.info["field"]]["B"] = [float(c) for c in v.value]
            elif v.kind == "keyframes":
                f = data["fields"][v.info["field"]]
                f.pop("file", None)
                f["times"] = [float(t) for t in v.info["times"]]
                f["values"] = [[float(c) for c in row] for row in v.value.reshape(-1, 3)]
            elif v.kind == "epm":
                f = data["fields"][v.info["field"]]
                f["position"] = [float(c) for c in v.value[:3]]
                f["moment"] = [float(c) for c in v.value[3:]]
        return data


__all__ = ["Design", "KINDS", "Variable", "body_variables", "check_request"]
