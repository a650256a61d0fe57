"""`SoundScene`: which geoms of a MuJoCo model sound, with which material and modal model.

A geom *sounds* when it can collide (``contype`` or ``conaffinity`` non-zero, or it is named
in an explicit ``<pair>``), is not a plane/height field, and has an acoustic material. The
material comes from, in this order of precedence:

1. the Python mapping ``materials={geom_or_body_name: material}`` (a geom name wins over its
   body's name; a value of ``None``/``"none"``/``"silent"`` makes the geom silent),
2. an MJCF custom text ``<custom><text name="mjsound:GEOMNAME" data="steel"/></custom>``,
3. the geom's MJCF ``material`` name when it names a known acoustic material
   (case-insensitive, see :func:`mjsound.materials.get_material`).

Geoms with no acoustic material are silent but still excite what they hit; a plane (e.g. the
floor) may carry a material, which is then used for the contact (Hertz) pulse of the objects
hitting it, but it never gets a modal model.

Meshes come from the compiled model, in the geom frame (mesh geoms from ``mesh_vert`` /
``mesh_face``; primitives as built-in shape specs of the right size). Modal models come from
:func:`mjsound.modal.analyze.analyze` (disk-cached) with an optional tqdm progress bar.

A scene budget ``budget_modes`` (total modes over all sounding geoms) is shared by
importance: every sounding geom keeps at least a few modes (never silently dropped), the rest
go greedily to the loudest next-lowest mode of any geom (loudness per unit impulse at 1 m:
``|radiation_i| * rms(phi_i) / omega_i``). Every truncation is listed in :meth:`report`.
"""

from __future__ import annotations

import heapq
import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..materials import Material, get_material, parse_material
from ..modal.model import ModalModel

__all__ = ["SoundScene", "SoundingGeom", "geom_mesh_spec", "geom_contact_radius"]

_SILENT_WORDS = {"none", "silent", "off", ""}


def _mujoco():
    import mujoco

    return mujoco


@dataclass
class SoundingGeom:
    """One geom that sounds.

    Attributes
    ----------
    geom_id, body_id : int
        MuJoCo ids.
    name : str
        Synthesizer object name (the geom name, or ``geom<ID>`` for unnamed geoms).
    material : Material
    model : ModalModel
        The (possibly budget-truncated) model the synthesizer plays.
    n_modes_analysed : int
        Modes the analysis produced before the budget.
    source : str
        Where the material came from: ``mapping``, ``custom``, ``mjcf-material``.
    mesh : str
        Built-in spec or ``mesh:NAME`` that was analysed.
    dynamic : bool
        Whether the geom moves (its body is not welded to the world).
    """

    geom_id: int
    body_id: int
    name: str
    material: Material
    model: ModalModel
    n_modes_analysed: int
    source: str
    mesh: str
    dynamic: bool = True
    method: str = "hex"


@dataclass
class SoundScene:
    """Sounding geoms, their materials and modal models, and the microphones of a model.

    Build it with :meth:`from_model`. Attributes are read-only by convention.

    Attributes
    ----------
    model : mujoco.MjModel
    sounding : list[SoundingGeom]
        In geom-id order.
    geom_material : list[Material | None]
        Acoustic material of every geom (silent geoms and planes may have one too).
    silent : dict[str, str]
        Geom name -> why it does not sound.
    mic_site_ids : list[int]
        Microphone sites (follow their bodies); empty when ``mic_positions`` is fixed.
    mic_positions : (m, 3) array
        Microphone positions at the initial state [m].
    mic_names : list[str]
    budget_modes : int | None
    budget_notes : list[str]
        One line per geom whose model the budget truncated.
    sample_rate : int
        Sample rate the models were analysed for [Hz].
    """

    model: object
    sounding: list = field(default_factory=list)
    geom_material: list = field(default_factory=list)
    silent: dict = field(default_factory=dict)
    mic_site_ids: list = field(default_factory=list)
    mic_positions: np.ndarray = field(default_factory=lambda: np.zeros((1, 3)))
    mic_names: list = field(default_factory=list)
    budget_modes: int | None = None
    budget_notes: list = field(default_factory=list)
    sample_rate: int = 48000
    analysis_seconds: float = 0.0

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_model(
        cls,
        model,
        materials: dict | None = None,
        microphones=None,
        budget_modes: int | None = None,
        sample_rate: int = 48000,
        quality: str = "default",
        progress: bool = True,
        *,
        method: str = "hex",
        models: dict | None = None,
        cache: bool = True,
    ) -> "SoundScene":
        """Build the scene of a model.

        Parameters
        ----------
        model : mujoco.MjModel | str | os.PathLike
            A compiled model or a path to an MJCF file.
        materials : dict, optional
            ``{geom_or_body_name: material}``; values are anything
            :func:`mjsound.materials.parse_material` accepts, or ``None``/``"silent"``.
        microphones : list[str] | (m, 3) array, optional
            Site names (they follow their bodies) or fixed world positions [m]. Default: the
            sites whose name starts with ``mic`` in model order, else one listener 1 m from the
            centre of the scene.
        budget_modes : int, optional
            Total modes over all sounding geoms (None: no limit).
        sample_rate : int
            Audio sample rate [Hz]; modes above ``0.45 * sample_rate`` are not computed.
        quality : str
            Passed to ``analyze`` (``"draft"``, ``"default"``, ``"high"``).
        progress : bool
            Show a tqdm progress bar over the analyses.
        method : str
            Discretization (``"hex"`` default); on failure falls back to ``hex``, then silence.
        models : dict, optional
            Precomputed ``{geom_name: ModalModel}``; those geoms skip analysis.
        cache : bool
            Use the on-disk model cache.

        Returns
        -------
        SoundScene
        """
        mujoco = _mujoco()
        if not isinstance(model, mujoco.MjModel):
            model = mujoco.MjModel.from_xml_path(os.fspath(model))
        scene = cls(model=model, budget_modes=budget_modes, sample_rate=int(sample_rate))
        materials = dict(materials or {})
        models = dict(models or {})
        custom = _custom_materials(model)

        # ---------------------------------------------------------------- materials
        pair_geoms = set(np.asarray(model.pair_geom1).tolist()) | set(np.asarray(model.pair_geom2).tolist())
        todo = []  # (g, name, material, source)
        for g in range(model.ngeom):
            gname = geom_name(model, g)
            bname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g])) or ""
            mat, source = None, None
            raw_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
            for key in (raw_name, bname):
                if key and key in materials:
                    mat, source = materials[key], "mapping"
                    break
            if source is None and raw_name and raw_name in custom:
                mat, source = custom[raw_name], "custom"
            if source is None and model.geom_matid[g] >= 0:
                mname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MATERIAL, int(model.geom_matid[g])) or ""
                try:
                    mat, source = get_material(mname), "mjcf-material"
                except KeyError:
                    mat, source = None, None
            if mat is not None and not isinstance(mat, Material):
                if isinstance(mat, str) and mat.strip().lower() in _SILENT_WORDS:
                    mat = None
                else:
                    try:
                        mat = parse_material(mat)
                    except (KeyError, ValueError) as exc:
                        raise ValueError(f"geom {gname!r}: bad acoustic material ({source}): {exc}") from exc
            scene.geom_material.append(mat)
            collides = bool(model.geom_contype[g] or model.geom_conaffinity[g] or g in pair_geoms)
            gtype = int(model.geom_type[g])
            if not collides:
                scene.silent[gname] = "cannot collide (contype = conaffinity = 0)"
            elif mat is None:
                scene.silent[gname] = "no acoustic material"
            elif gtype == mujoco.mjtGeom.mjGEOM_PLANE:
                scene.silent[gname] = f"plane (never analysed; material {mat.name} used for contacts)"
            elif gtype in (mujoco.mjtGeom.mjGEOM_HFIELD, getattr(mujoco.mjtGeom, "mjGEOM_SDF", -99)):
                scene.silent[gname] = "height field / SDF (not analysed)"
            else:
                todo.append((g, gname, mat, source))

        # ---------------------------------------------------------------- analysis
        import time as _time

        t0 = _time.perf_counter()
        analysed = []
        it = todo
        if progress and todo and any(name not in models for _, name, _, _ in todo):
            try:
                from tqdm.auto import tqdm

                it = tqdm(todo, desc="mjsound: modal analysis", unit="geom")
            except ImportError:  # pragma: no cover
                pass
        for g, gname, mat, source in it:
            spec, label = geom_mesh_spec(model, g)
            inaudible = _sphere_inaudible(model, g, mat, sample_rate)
            if gname in models:
                mm = models[gname]
            elif inaudible:
                scene.silent[gname] = inaudible
                continue
            else:
                mm = _analyze_with_fallback(gname, spec, mat, method, quality, sample_rate, cache)
            if mm is None:
                scene.silent[gname] = "analysis failed (see warning)"
                continue
            if mm.n_modes == 0:
                scene.silent[gname] = "no audible modes below f_max"
                continue
            body = int(model.geom_bodyid[g])
            analysed.append(
                SoundingGeom(
                    geom_id=g,
                    body_id=body,
                    name=gname,
                    material=mat,
                    model=mm,
                    n_modes_analysed=mm.n_modes,
                    source=source,
                    mesh=label,
                    dynamic=bool(model.body_weldid[body] != 0),
                    method=str(mm.method),
                )
            )
        scene.analysis_seconds = _time.perf_counter() - t0
        scene.sounding = analysed
        scene._apply_budget()
        scene._setup_microphones(microphones)
        return scene

    # ------------------------------------------------------------------ budget
    def _apply_budget(self) -> None:
        total = sum(s.model.n_modes for s in self.sounding)
        if self.budget_modes is None or total <= self.budget_modes or not self.sounding:
            return
        budget = int(self.budget_modes)
        n_geoms = len(self.sounding)
        floor = max(1, min(8, budget // (2 * n_geoms)))
        counts = [min(s.model.n_modes, floor) for s in self.sounding]
        scores = [_mode_loudness(s.model) for s in self.sounding]
        left = budget - sum(counts)
        heap = [(-scores[i][counts[i]], i) for i in range(n_geoms) if counts[i] < len(scores[i])]
        heapq.heapify(heap)
        while left > 0 and heap:
            _, i = heapq.heappop(heap)
            counts[i] += 1
            left -= 1
            if counts[i] < len(scores[i]):
                heapq.heappush(heap, (-scores[i][counts[i]], i))
        for s, n in zip(self.sounding, counts):
            if n < s.model.n_modes:
                f_top = s.model.frequencies_hz[n - 1] if n else 0.0
                self.budget_notes.append(
                    f"{s.name}: {s.model.n_modes} -> {n} modes (budget {budget}; kept up to {f_top:.0f} Hz)"
                )
                s.model = s.model.truncated(n_modes=n)
        if sum(counts) > budget:
            self.budget_notes.append(
                f"budget {budget} < {sum(counts)}: every sounding geom keeps at least {floor} modes"
            )

    # ------------------------------------------------------------------ microphones
    def _setup_microphones(self, microphones) -> None:
        mujoco = _mujoco()
        model = self.model
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        if microphones is None:
            ids = []
            for s in range(model.nsite):
                name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) or ""
                if name.lower().startswith("mic"):
                    ids.append(s)
            if ids:
                self.mic_site_ids = ids
            else:
                self.mic_positions = np.asarray([self._default_listener(data)])
                self.mic_names = ["listener"]
                return
        elif len(microphones) and isinstance(microphones[0], str):
            ids = []
            for name in microphones:
                sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
                if sid < 0:
                    raise ValueError(f"microphone site {name!r} not in the model")
                ids.append(sid)
            self.mic_site_ids = ids
        else:
            pos = np.asarray(microphones, dtype=np.float64).reshape(-1, 3)
            if not np.isfinite(pos).all():
                raise ValueError("microphone positions must be finite")
            self.mic_positions = pos
            self.mic_names = [f"mic{i}" for i in range(len(pos))]
            return
        self.mic_names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) for s in self.mic_site_ids]
        self.mic_positions = np.array(data.site_xpos[self.mic_site_ids], dtype=np.float64)

    def _default_listener(self, data) -> np.ndarray:
        """1 m from the scene centre, 30 degrees above the horizon, towards -y [m]."""
        if self.sounding:
            pts = np.array([data.geom_xpos[s.geom_id] for s in self.sounding])
        else:
            dyn = [b for b in range(1, self.model.nbody)]
            pts = np.array(data.xpos[dyn]) if dyn else np.zeros((1, 3))
        centre = pts.mean(axis=0) if len(pts) else np.zeros(3)
        return centre + np.array([0.0, -np.cos(np.pi / 6), np.sin(np.pi / 6)])

    @property
    def mics_move(self) -> bool:
        """Whether any microphone site sits on a moving body."""
        m = self.model
        return any(m.body_weldid[m.site_bodyid[s]] != 0 for s in self.mic_site_ids)

    # ------------------------------------------------------------------ reporting
    @property
    def n_modes(self) -> int:
        """Total modes the synthesizer plays."""
        return int(sum(s.model.n_modes for s in self.sounding))

    def by_geom(self) -> dict:
        """``{geom_id: SoundingGeom}``."""
        return {s.geom_id: s for s in self.sounding}

    def summary(self) -> dict:
        """JSON-able description of the scene."""
        return {
            "sounding": [
                {
                    "geom": s.name,
                    "material": s.material.name,
                    "material_source": s.source,
                    "mesh": s.mesh,
                    "method": s.method,
                    "n_modes": s.model.n_modes,
                    "n_modes_analysed": s.n_modes_analysed,
                    "f_min_hz": float(s.model.frequencies_hz[0]) if s.model.n_modes else None,
                    "f_max_hz": float(s.model.frequencies_hz[-1]) if s.model.n_modes else None,
                    "dofs": int(s.model.dofs),
                    "seconds": float(s.model.seconds),
                }
                for s in self.sounding
            ],
            "silent": dict(self.silent),
            "n_modes": self.n_modes,
            "budget_modes": self.budget_modes,
            "budget_notes": list(self.budget_notes),
            "microphones": list(self.mic_names),
            "sample_rate": self.sample_rate,
            "analysis_seconds": self.analysis_seconds,
        }

    def report(self) -> str:
        """Human-readable summary (what sounds, with how many modes, what was cut)."""
        lines = [f"{len(self.sounding)} sounding geom(s), {self.n_modes} modes, mics: {', '.join(self.mic_names)}"]
        for s in self.sounding:
            f = s.model.frequencies_hz
            rng = f"{f[0]:.0f}-{f[-1]:.0f} Hz" if len(f) else "-"
            cut = f" (of {s.n_modes_analysed})" if s.model.n_modes != s.n_modes_analysed else ""
            lines.append(f"  {s.name:<20s} {s.material.name:<14s} {s.model.n_modes:4d} modes{cut}  {rng}  [{s.mesh}]")
        for note in self.budget_notes:
            lines.append(f"  budget: {note}")
        for name, why in self.silent.items():
            lines.append(f"  silent {name}: {why}")
        return "\n".join(lines)


# ---------------------------------------------------------------------- helpers
def geom_name(model, g: int) -> str:
    """The geom's name, or ``geom<ID>`` when it has none."""
    mujoco = _mujoco()
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or f"geom{int(g)}"


def _custom_materials(model) -> dict:
    """``{geom_name: material text}`` from custom texts named ``mjsound:GEOMNAME``."""
    mujoco = _mujoco()
    out = {}
    for t in range(model.ntext):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TEXT, t) or ""
        if not name.startswith("mjsound:"):
            continue
        adr, size = int(model.text_adr[t]), int(model.text_size[t])
        raw = bytes(model.text_data[adr : adr + size - 1])
        out[name[len("mjsound:") :]] = raw.decode("utf-8", "replace").strip()
    return out


def geom_mesh_spec(model, g: int):
    """What to analyse for geom ``g``: a built-in spec or ``(vertices, faces)`` in the geom frame.

    Returns
    -------
    (mesh, label) : (str | tuple[np.ndarray, np.ndarray], str)
        ``mesh`` for :func:`analyze`; ``label`` a short description.

    Raises
    ------
    ValueError
        For planes, height fields and SDFs.
    """
    mujoco = _mujoco()
    T = mujoco.mjtGeom
    t = int(model.geom_type[g])
    s = np.asarray(model.geom_size[g], dtype=np.float64)
    fmt = lambda *v: ",".join(f"{x:.6g}" for x in v)  # noqa: E731
    if t == T.mjGEOM_SPHERE:
        spec = f"sphere:{fmt(s[0])}"
        return spec, spec
    if t == T.mjGEOM_BOX:
        spec = f"box:{fmt(*(2 * s))}"
        return spec, spec
    if t == T.mjGEOM_CYLINDER:
        spec = f"cylinder:{fmt(s[0], 2 * s[1])}"
        return spec, spec
    if t == T.mjGEOM_CAPSULE:
        spec = f"capsule:{fmt(s[0], 2 * s[1])}"
        return spec, spec
    if t == T.mjGEOM_ELLIPSOID:
        import trimesh

        sph = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
        return (np.asarray(sph.vertices) * s[None, :], np.asarray(sph.faces)), f"ellipsoid:{fmt(*s)}"
    if t == T.mjGEOM_MESH:
        mid = int(model.geom_dataid[g])
        va, vn = int(model.mesh_vertadr[mid]), int(model.mesh_vertnum[mid])
        fa, fn = int(model.mesh_faceadr[mid]), int(model.mesh_facenum[mid])
        v = np.array(model.mesh_vert[va : va + vn], dtype=np.float64)
        f = np.array(model.mesh_face[fa : fa + fn], dtype=np.int64)
        mname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MESH, mid) or str(mid)
        return (v, f), f"mesh:{mname} ({vn} vertices)"
    raise ValueError(f"geom {geom_name(model, g)!r}: type {t} has no mesh to analyse")


def geom_contact_radius(model, g: int) -> float:
    """Radius of curvature for Hertz contact [m] (inf for planes and flat boxes)."""
    mujoco = _mujoco()
    T = mujoco.mjtGeom
    t = int(model.geom_type[g])
    s = model.geom_size[g]
    if t in (T.mjGEOM_SPHERE, T.mjGEOM_CAPSULE, T.mjGEOM_CYLINDER):
        return float(s[0])
    if t == T.mjGEOM_ELLIPSOID:
        return float(np.min(s))
    if t == T.mjGEOM_MESH:
        # A mesh touches with its edges and corners; a tenth of its bounding radius.
        return float(0.1 * model.geom_rbound[g]) if model.geom_rbound[g] > 0 else np.inf
    return np.inf


def _sphere_inaudible(model, g, mat, sample_rate) -> str | None:
    """Why a solid sphere is too small/stiff to ring below f_max, or None.

    The lowest mode of a free solid sphere (spheroidal n=0, l=2) is at
    ``omega R / c_s ~ 2.6`` (nu 0..0.45), ``c_s = sqrt(G / rho)``; a margin of two keeps it safe.
    """
    mujoco = _mujoco()
    if int(model.geom_type[g]) != mujoco.mjtGeom.mjGEOM_SPHERE:
        return None
    R = float(model.geom_size[g][0])
    f1 = 2.6 * np.sqrt(mat.shear_modulus / mat.rho) / (2 * np.pi * R)
    f_max = min(20000.0, 0.45 * float(sample_rate))
    if 0.5 * f1 > f_max:
        return f"no audible modes (lowest mode ~{f1 / 1000:.0f} kHz > f_max {f_max / 1000:.1f} kHz); still excites what it hits"
    return None


def _mode_loudness(mm: ModalModel) -> np.ndarray:
    """Pressure per unit impulse at 1 m of each mode (ranking only) [Pa / (N s)]."""
    if mm.n_modes == 0:
        return np.zeros(0)
    rms = np.sqrt(np.mean(np.sum(mm.shapes.astype(np.float64) ** 2, axis=1), axis=0))
    rad = np.abs(mm.radiation)
    if not np.any(rad > 0):
        rad = mm.omega**2  # plain modal acceleration
    return rms * rad / mm.omega


def _analyze_with_fallback(name, spec, material, method, quality, sample_rate, cache):
    """``analyze`` with ``method``, then ``hex``; ``None`` (and a warning) when both fail."""
    from ..modal.analyze import analyze

    tried = []
    for m in dict.fromkeys([method, "hex"]):
        try:
            return analyze(spec, material, method=m, quality=quality, sample_rate=sample_rate, cache=cache, progress=False)
        except (ValueError, RuntimeError, MemoryError) as exc:
            tried.append(f"{m}: {exc}")
    warnings.warn(f"geom {name!r} stays silent: modal analysis failed ({'; '.join(tried)})", stacklevel=3)
    return None
