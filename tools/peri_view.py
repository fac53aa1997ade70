"""What a peridrive run holds, for the plotting tools: its bodies and their kinds, the view that
fits them, the length and time units that fit its extent and duration, and a note of every figure
drawn (OUTDIR/figures.json: view, projection, unit and colour limits of each figure).

  run = peri_view.Run(OUTDIR)        # bodies, kinds, reference positions, the chosen view and unit
  peri_view.length_unit(0.05)        # ('mm', 1e-3): lengths shown between 1 and 1000 units
  peri_view.choose_view(["solid"])   # 'solid': a mid-plane slice and the damaged region in 3D
Needs Debian's python3-h5py, python3-numpy, python3-matplotlib and python3-yaml.
"""
import json
import os
import sys

import h5py
import numpy as np
import yaml

# Damage (broken-bond fraction) is always drawn on [0, 1], whatever the run holds: an undamaged
# body shows the colour of 0, not the top of an empty range.
DAMAGE_LIMITS = (0.0, 1.0)
DAMAGE_CMAP = "inferno"

# Views by the body kinds of a run (the scene's kind names; "sphere" is a spherical membrane).
SHEET_KINDS = {"membrane", "lattice"}


def length_unit(extent):
    """(name, metres per unit) showing `extent` [m] as 1 to 1000 units (nm below, m above)."""
    for name, scale in (("m", 1.0), ("mm", 1e-3), ("um", 1e-6)):
        if extent >= scale:
            return name, scale
    return "nm", 1e-9


def time_unit(duration):
    """(name, seconds per unit) showing `duration` [s] as 1 to 1000 units (ns below, s above)."""
    for name, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6)):
        if duration >= scale:
            return name, scale
    return "ns", 1e-9


def choose_view(kinds):
    """The view that fits bodies of these kinds: 'sheet' (flat membranes and lattices: a sheet seen
    from above), 'solid' (blocks: a mid-plane slice and the damaged region in 3D), 'curves'
    (fibers: 3D curves), 'sphere' (spherical membranes: 3D) or, for a mix, 'scatter3d'."""
    kinds = set(kinds)
    if kinds and kinds <= SHEET_KINDS:
        return "sheet"
    if kinds == {"solid"}:
        return "solid"
    if kinds == {"fiber"}:
        return "curves"
    if kinds == {"sphere"}:
        return "sphere"
    return "scatter3d"


def scene_text(outdir):
    """The run's resolved scene: frames.h5's /scene dataset (or its older `scene` attribute), else
    scene.resolved.yaml."""
    path = os.path.join(outdir, "frames.h5")
    if os.path.exists(path):
        with h5py.File(path, "r") as f:
            if "scene" in f:
                return f["scene"].asstr()[()]
            if "scene" in f.attrs:
                v = f.attrs["scene"]
                return v.decode() if isinstance(v, bytes) else str(v)
    with open(os.path.join(outdir, "scene.resolved.yaml"), encoding="utf-8") as f:
        return f.read()


class Run:
    """A run's bodies (name, kind, node indices) and reference configuration; the view and the
    length unit that fit them."""

    def __init__(self, outdir):
        self.outdir = outdir
        self.h5 = os.path.join(outdir, "frames.h5")
        if not os.path.exists(self.h5):
            raise SystemExit(f"{self.h5}: not found; expected a peridrive output directory")
        self.scene = yaml.safe_load(scene_text(outdir))
        bodies = self.scene.get("bodies") or {}
        self.body_names = list(bodies)
        self.kinds = [(bodies[b] or {}).get("kind", "membrane") for b in self.body_names]
        with h5py.File(self.h5, "r") as f:
            self.reference = f["mesh/reference_position"][...]
            self.body = f["mesh/body"][...].astype(int)
            # Mesh membranes' triangles (natural ids) as frame indices; with a node selection,
            # only those whose three corners the frames hold. None: no mesh membrane.
            self.triangles = None
            if "mesh/triangles" in f:
                tris = f["mesh/triangles"][...].astype(np.int64)
                if "mesh/natural_id" in f:
                    natural = f["mesh/natural_id"][...].astype(np.int64)
                    at = np.searchsorted(natural, tris)
                    at = np.minimum(at, len(natural) - 1)
                    held = (natural[at] == tris).all(axis=1)
                    tris = at[held]
                self.triangles = tris
            self.frame_names = sorted(f["frames"].keys())
        if not self.frame_names:
            raise SystemExit(f"{self.h5}: no complete frame")
        self.view = choose_view(self.kinds)
        self.extent = float(np.ptp(self.reference, axis=0).max()) if len(self.reference) else 0.0
        self.unit, self.scale = length_unit(self.extent)

    def require(self, tool, *fields):
        """Exit with status 2, naming the tool and the fields, when the frames lack any of them (a
        scene's output.fields chose which they hold)."""
        with h5py.File(self.h5, "r") as f:
            held = set(f["frames"][self.frame_names[0]].keys())
        missing = [name for name in fields if name not in held]
        if missing:
            print(f"{tool}: the frames of {os.path.dirname(self.h5)} hold no {', '.join(missing)} (output.fields: "
                  f"{', '.join(sorted(held))}); run the scene with them", file=sys.stderr)
            sys.exit(2)

    def nodes_of(self, kind):
        """Mask of the nodes of bodies of `kind`."""
        ids = [k for k, kd in enumerate(self.kinds) if kd == kind]
        return np.isin(self.body, ids)

    def frame(self, k):
        """Frame k (negative: from the end): time, step, position, displacement, damage. A frame
        holds the fields the scene's output.fields chose: position and displacement stand for each
        other (with the reference positions), and a field neither gives is None."""
        with h5py.File(self.h5, "r") as f:
            g = f["frames"][self.frame_names[k]]
            get = lambda name: g[name][...].astype(float) if name in g else None
            position, displacement = get("position"), get("displacement")
            if position is None and displacement is not None:
                position = self.reference + displacement
            if displacement is None and position is not None:
                displacement = position - self.reference
            return dict(time=float(g.attrs["time"]), step=int(g.attrs["step"]), position=position,
                        displacement=displacement, damage=get("damage"))

    def spacing(self):
        """Median distance between consecutive nodes (natural order): the grid spacing of grids."""
        d = np.linalg.norm(np.diff(self.reference, axis=0), axis=1)
        d = d[d > 0]
        return float(np.median(d)) if len(d) else 1.0


def note(outdir, figure, tool, view, fig, mappable=None, unit=None):
    """Record what `figure` shows in OUTDIR/figures.json, read from the drawn figure itself: the
    projection of its axes (rectilinear or 3d), the length unit of their x labels, the colour
    limits and map of `mappable` (the damage colouring, where there is one)."""
    path = os.path.join(outdir, "figures.json")
    notes = {}
    if os.path.exists(path):
        with open(path) as f:
            notes = json.load(f)
    axes = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    units = sorted({ax.get_xlabel().rsplit("[", 1)[-1].rstrip("]") for ax in axes if "[" in ax.get_xlabel()})
    entry = dict(tool=tool, view=view, projections=sorted({ax.name for ax in axes}), axis_units=units,
                 length_unit=unit)
    if mappable is not None:
        lo, hi = mappable.get_clim()
        entry.update(color_limits=[float(lo), float(hi)], colormap=mappable.get_cmap().name)
    notes[figure] = entry
    with open(path, "w") as f:
        json.dump(notes, f, indent=1, sort_keys=True)


def sheet_triangles(ref):
    """Delaunay triangles of the reference (x, y) positions, as index triples into `ref`."""
    import matplotlib.tri as mtri
    if len(ref) < 3:
        return np.zeros((0, 3), dtype=int)
    return mtri.Triangulation(ref[:, 0], ref[:, 1]).triangles.astype(int)


def whole_pieces(tris, ref, cur, damage, critical_stretch=None, gap_damage=0.5):
    """The pieces a torn surface holds: triangles (index triples) left whole -- no corner with
    damage >= gap_damage, no edge stretched beyond critical_stretch (current / reference length;
    None: no such test), the rule tools/render3d.py draws by -- joined across shared edges. Returns
    one label per triangle: the piece (0, 1, ..., largest first), -1 where it is not whole."""
    tris = np.asarray(tris)
    whole = ~(damage[tris] >= gap_damage).any(axis=1)
    if critical_stretch:
        i, j = tris, np.roll(tris, -1, axis=1)
        lref = np.linalg.norm(ref[i] - ref[j], axis=2)
        lcur = np.linalg.norm(cur[i] - cur[j], axis=2)
        whole &= ~(lcur > critical_stretch * lref).any(axis=1)
    parent = np.arange(len(tris))

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    owner = {}
    for t in np.nonzero(whole)[0]:
        for a, b in zip(tris[t], np.roll(tris[t], -1)):
            key = (min(a, b), max(a, b))
            if key in owner:
                ra, rb = find(owner[key]), find(t)
                if ra != rb:
                    parent[ra] = rb
            else:
                owner[key] = t
    labels = np.full(len(tris), -1)
    kept = np.nonzero(whole)[0]
    if kept.size:
        roots = np.array([find(t) for t in kept])
        uniq, inverse, counts = np.unique(roots, return_inverse=True, return_counts=True)
        rank = np.empty(len(uniq), dtype=int)
        rank[np.argsort(-counts, kind="stable")] = np.arange(len(uniq))
        labels[kept] = rank[inverse]
    return labels
