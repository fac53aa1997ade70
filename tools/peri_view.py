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
import re
import sys
import time

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


# The run directories a tool has opened (require_run): run_tool reads the last again when a run
# writing it changed frames.h5 under the tool.
_opened = []


# The run directories whose state (failed, unfinished) has been reported once.
_reported = set()


def run_state(outdir):
    """"complete" (summary.json, written last), "failed" (the FAILED file a run that stopped on an
    error leaves; its first line is the error), "live" (is_live) or "unfinished" (stopped by a
    signal, killed, or a copy taken mid-run)."""
    if os.path.exists(os.path.join(outdir, "FAILED")):
        return "failed"
    if os.path.exists(os.path.join(outdir, "summary.json")):
        return "complete"
    return "live" if is_live(outdir) else "unfinished"


def report_state(outdir):
    """A warning on stderr, once per directory, when the run failed or did not finish: the tools
    still draw what it wrote (a failed run's last frames are what one looks at to see why), but
    the figures are not those of a complete run."""
    if outdir in _reported:
        return
    _reported.add(outdir)
    state = run_state(outdir)
    if state == "failed":
        try:
            with open(os.path.join(outdir, "FAILED"), encoding="utf-8", errors="replace") as f:
                why = f.readline().strip()
        except OSError:
            why = ""
        print(f"warning: {outdir}: the run failed ({why[:200] or 'see its FAILED file'}); what follows shows "
              "the frames and rows it wrote before it stopped", file=sys.stderr)
    elif state == "unfinished":
        print(f"warning: {outdir}: the run did not finish (no summary.json: stopped by a signal, killed, or "
              "copied mid-run); what follows shows the frames and rows it wrote", file=sys.stderr)


def require_run(outdir):
    """Exit with a message unless `outdir` holds a run's frames.h5 (report_state: a warning when
    the run failed or did not finish)."""
    path = os.path.join(outdir, "frames.h5")
    if not os.path.isfile(path):
        what = "no such directory" if not os.path.isdir(outdir) else "no frames.h5 in it"
        raise SystemExit(f"{outdir}: {what}; expected a peridrive output directory")
    _opened.append(outdir)
    report_state(outdir)
    return path


def is_live(outdir, quiet_seconds=60.0):
    """Whether a run seems to be writing `outdir`: no summary.json (written last) nor FAILED, and
    frames.h5 modified within the last `quiet_seconds`."""
    try:
        age = time.time() - os.path.getmtime(os.path.join(outdir, "frames.h5"))
    except OSError:
        return False
    done = any(os.path.exists(os.path.join(outdir, name)) for name in ("summary.json", "FAILED"))
    return not done and age < quiet_seconds


def run_tool(main, wait=60.0):
    """Runs a tool's main(). A run still writing frames.h5 leaves it consistent only after each
    frame's flush (parallel HDF5 offers readers nothing between), so a read may fail while the
    run writes the next frame (h5py: "Unable to open object", "bad heap free list", a truncated
    file). Such a failure in a live run's directory (is_live) runs main again after a pause, for
    up to `wait` seconds; any other error is raised as it is."""
    deadline = time.monotonic() + wait
    while True:
        try:
            return main()
        except (OSError, KeyError) as e:
            if not (_opened and "Unable to" in str(e) and is_live(_opened[-1]) and time.monotonic() < deadline):
                if isinstance(e, OSError) and e.filename:  # a file the tool cannot write or read
                    raise SystemExit(f"{e.filename}: {e.strerror or e}") from None
                raise
            print(f"{_opened[-1]}: frames.h5 changed while it was read (a run is writing it); reading it again",
                  file=sys.stderr)
            del _opened[:]
            time.sleep(0.5)


def open_frames(outdir, wait=10.0):
    """The run's frames.h5, opened read-only. A run that is still writing it leaves it consistent
    only after each frame's flush: opening it meanwhile may fail (HDF5 reports a truncated file),
    so in a live run's directory (is_live) the open is retried for `wait` seconds before the tool
    exits with a message."""
    path = require_run(outdir)
    deadline = time.monotonic() + wait
    while True:
        try:
            return h5py.File(path, "r")
        except OSError as e:
            if not is_live(outdir):
                raise SystemExit(f"{path}: cannot be read ({e})") from None
            if time.monotonic() >= deadline:
                raise SystemExit(f"{path}: cannot be read ({e}); a run is writing it: try again after its "
                                 "next frame") from None
            time.sleep(0.25)


def frame_names(f, outdir):
    """The names of the complete frames of an open frames.h5, in order: those frames.xdmf lists
    (rewritten only after frames are flushed, so a frame a running run is writing is left out),
    or every frame where there is no frames.xdmf."""
    names = sorted(f["frames"].keys())
    try:
        with open(os.path.join(outdir, "frames.xdmf"), encoding="utf-8") as x:
            listed = set(re.findall(r"frames\.h5:/frames/(\w+)/", x.read()))
    except OSError:
        return names
    return [name for name in names if name in listed]


def scene_text(outdir):
    """The run's resolved scene: frames.h5's /scene dataset (or its older `scene` attribute), else
    scene.resolved.yaml."""
    path = os.path.join(outdir, "frames.h5")
    if os.path.exists(path):
        with open_frames(outdir) as f:
            if "scene" in f:
                return f["scene"].asstr()[()]
            if "scene" in f.attrs:
                v = f.attrs["scene"]
                return v.decode() if isinstance(v, bytes) else str(v)
    path = os.path.join(outdir, "scene.resolved.yaml")
    if not os.path.isfile(path):
        require_run(outdir)  # (exits: neither file)
    with open(path, encoding="utf-8") as f:
        return f.read()


class Run:
    """A run's bodies (name, kind, node indices) and reference configuration; the view and the
    length unit that fit them."""

    def __init__(self, outdir):
        self.outdir = outdir
        self.h5 = require_run(outdir)
        self.scene = yaml.safe_load(scene_text(outdir))
        bodies = self.scene.get("bodies") or {}
        self.body_names = list(bodies)
        self.kinds = [(bodies[b] or {}).get("kind", "membrane") for b in self.body_names]
        with self.open() as f:
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
            self.frame_names = frame_names(f, outdir)
        if not self.frame_names:
            raise SystemExit(f"{self.h5}: no complete frame")
        self.view = choose_view(self.kinds)
        self.extent = float(np.ptp(self.reference, axis=0).max()) if len(self.reference) else 0.0
        self.unit, self.scale = length_unit(self.extent)

    def open(self):
        """frames.h5, opened read-only (open_frames: retried while a run writes a frame)."""
        return open_frames(self.outdir)

    def require(self, tool, *fields):
        """Exit with status 2, naming the tool and the fields, when the frames lack any of them (a
        scene's output.fields chose which they hold)."""
        with self.open() as f:
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
        n = len(self.frame_names)
        if not -n <= k < n:
            raise SystemExit(f"{self.outdir}: frame {k}: the run holds frames 0 .. {n - 1} (or -{n} .. -1)")
        with self.open() as f:
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
        try:
            with open(path) as f:
                notes = json.load(f)
        except (OSError, ValueError):
            notes = {}  # unreadable or corrupt: started afresh
        if not isinstance(notes, dict):
            notes = {}
    axes = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    units = sorted({ax.get_xlabel().rsplit("[", 1)[-1].rstrip("]") for ax in axes if "[" in ax.get_xlabel()})
    entry = dict(tool=tool, view=view, projections=sorted({ax.name for ax in axes}), axis_units=units,
                 length_unit=unit)
    if mappable is not None:
        lo, hi = mappable.get_clim()
        entry.update(color_limits=[float(lo), float(hi)], colormap=mappable.get_cmap().name)
    notes[figure] = entry
    # Written beside and renamed over, so that a reader (or a second tool) never sees half of it;
    # a directory the user may not write (a shared run) gets no notes, only a warning.
    tmp = f"{path}.{os.getpid()}.tmp"
    try:
        with open(tmp, "w") as f:
            json.dump(notes, f, indent=1, sort_keys=True)
        os.replace(tmp, path)
    except OSError as e:
        print(f"warning: {path}: not written ({e.strerror}); the figures are saved without these notes", file=sys.stderr)


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
