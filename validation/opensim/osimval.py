"""Shared helpers for the OpenSim 4.6 side-by-side checks (run with the .opensim/venv Python).

Paths: the repository root is two levels above this file; reference data are read in place from
$MUSCULO_REFERENCE (default ../shared/reference beside the repository); everything written goes
under target/opensim-validation/.
"""

import math
import os
import re
import shutil
import subprocess
import sys

import numpy as np

os.environ.setdefault("OPENSIM_LOG_LEVEL", "warn")
import opensim as osim  # noqa: E402  (after the environment is set)

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
REFERENCE = os.path.abspath(
    os.environ.get("MUSCULO_REFERENCE", os.path.join(REPO, "..", "shared", "reference")))
MODELS = os.path.join(REFERENCE, "opensim-models")
WORK = os.path.join(REPO, "target", "opensim-validation")
MUSCULO = os.environ.get("MUSCULO_BIN", os.path.join(REPO, "target", "release", "musculo"))

DEG = 180.0 / math.pi


def quiet_opensim():
    """OpenSim logs every IK frame at `info` and every missing geometry file at `warn`: keep
    errors only."""
    osim.Logger.setLevelString("error")


# OpenSim opens ./opensim.log on its first message; the scripts keep their logs under WORK.
osim.Logger.removeFileSink()


def require(path, what):
    if not os.path.exists(path):
        sys.exit(f"missing {what}: {path} (set MUSCULO_REFERENCE to the shared reference folder)")
    return path


def fresh_dir(path):
    """Creates an empty folder (removing an old one: it only ever holds this script's outputs)."""
    if os.path.isdir(path):
        shutil.rmtree(path)
    os.makedirs(path)
    return path


def edit_setup(src, dst, replacements):
    """Copies an OpenSim setup file, replacing the text of the named elements.

    replacements: {element_name or "Parent/element_name": new_text}. The element must occur
    exactly once (in the Parent element when one is named; self-closing `<name />` forms
    included); everything else in the file is kept byte for byte.
    """
    with open(src, encoding="utf-8") as f:
        text = f.read()
    for key, value in replacements.items():
        parent, _, name = key.rpartition("/")
        start, end = 0, len(text)
        if parent:
            m = re.search(rf"<{parent}[\s>].*?</{parent}\s*>", text, re.S)
            if m is None:
                sys.exit(f"{src}: no <{parent}> element")
            start, end = m.span()
        pattern = re.compile(rf"<{name}\s*>[^<]*</{name}\s*>|<{name}\s*/>")
        part = text[start:end]
        hits = pattern.findall(part)
        if len(hits) != 1:
            sys.exit(f"{src}: expected one <{key}> element, found {len(hits)}")
        part = pattern.sub(lambda _m: f"<{name}>{value}</{name}>", part)
        text = text[:start] + part + text[end:]
    with open(dst, "w", encoding="utf-8") as f:
        f.write(text)
    return dst


def run_musculo(args, log_path):
    """Runs the musculo CLI; returns (ok, seconds, combined output)."""
    import time
    t0 = time.perf_counter()
    proc = subprocess.run([MUSCULO] + args, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    out = proc.stdout + proc.stderr
    with open(log_path, "w", encoding="utf-8") as f:
        f.write(f"$ {MUSCULO} {' '.join(args)}\nexit {proc.returncode}\n{out}")
    return proc.returncode == 0, dt, out


def example_names(example, model_path, folder, *keys):
    """The names a musculo example writes with `--names` (e.g. "coordinates", "markers"), as a
    tuple in the order of `keys`, or None with musculo's error."""
    import json
    out = os.path.join(folder, "names.json")
    proc = subprocess.run([example, model_path, "--names", out], capture_output=True, text=True)
    if proc.returncode != 0:
        return None, (proc.stderr.strip().splitlines() or ["?"])[-1]
    with open(out) as f:
        names = json.load(f)
    return tuple(names[k] for k in keys), None

def musculo_has(command):
    """Whether target/release/musculo exists and lists `command` among its subcommands."""
    if not os.path.exists(MUSCULO):
        return False
    proc = subprocess.run([MUSCULO, "--help"], capture_output=True, text=True)
    return re.search(rf"^\s+{command}\b", proc.stdout + proc.stderr, re.M) is not None


# ---------------------------------------------------------------------------------------------
# Motion files


def read_motion(path, model):
    """Reads an OpenSim .mot/.sto of coordinates with OpenSim's own reader.

    Returns (times, {coordinate: values in model units (rad or m)}). Columns that are not model
    coordinates are kept too (unconverted); rotational columns are converted from degrees when
    the header says inDegrees=yes (or has no inDegrees line: old SIMM files, in degrees), as
    OpenSim's Storage::convertDegreesToRadians does.
    """
    table = osim.TimeSeriesTable(path)
    if table.hasTableMetaDataKey("inDegrees"):
        in_degrees = table.getTableMetaDataAsString("inDegrees").strip().lower() == "yes"
    else:
        # Old SIMM motion files have no inDegrees line; SIMM wrote angles in degrees.
        in_degrees = True
    times = np.array(table.getIndependentColumn())
    coords = model.getCoordinateSet()
    out = {}
    for label in table.getColumnLabels():
        values = table.getDependentColumn(label).to_numpy().copy()
        name = label.split("/")[-2] if label.startswith("/") and label.endswith("/value") else label
        if coords.contains(name):
            if in_degrees and coords.get(name).getMotionType() == osim.Coordinate.Rotational:
                values = values / DEG
            out[name] = values
        else:
            out[label] = values
    return times, out


def read_sto_columns(path):
    """Reads a .sto/.mot with OpenSim's reader: (times, {label: values}) with no conversion."""
    table = osim.TimeSeriesTable(path)
    return (np.array(table.getIndependentColumn()),
            {lab: table.getDependentColumn(lab).to_numpy().copy()
             for lab in table.getColumnLabels()})


def is_rotational(coord):
    return coord.getMotionType() == osim.Coordinate.Rotational


def coordinate_unit(coord):
    """(factor to display units, unit name, tolerance in model units) for the IK comparison."""
    if is_rotational(coord):
        return DEG, "deg", 0.5 / DEG
    return 1000.0, "mm", 0.002


# ---------------------------------------------------------------------------------------------
# Random states


class Sampler:
    """Random states of one OpenSim model and the .mot that carries them to musculo."""

    def __init__(self, model):
        self.model = model
        self.state = model.initSystem()
        self.coords = model.getCoordinateSet()
        self.names = [self.coords.get(i).getName() for i in range(self.coords.getSize())]
        cs = model.getConstraintSet()
        self.couplers = []
        for i in range(cs.getSize()):
            c = osim.CoordinateCouplerConstraint.safeDownCast(cs.get(i))
            if c is not None and c.get_isEnforced():
                self.couplers.append(c)
        dependent = {c.getDependentCoordinateName() for c in self.couplers}
        self.free = [i for i in range(self.coords.getSize())
                     if self.names[i] not in dependent and not self.coords.get(i).getLocked(self.state)]

    def set(self, q):
        for i in range(self.coords.getSize()):
            self.coords.get(i).setValue(self.state, q[i], False)
        self.model.realizePosition(self.state)

    def complete(self, q):
        """q with the coupled coordinates set from the independent ones."""
        q = np.array(q, dtype=float)
        for c in self.couplers:
            ind = c.getIndependentCoordinateNames()
            x = osim.Vector(ind.getSize(), 0.0)
            for k in range(ind.getSize()):
                x.set(k, q[self.names.index(ind.get(k))])
            q[self.names.index(c.getDependentCoordinateName())] = c.getFunction().calcValue(x)
        return q

    def sample(self, n, seed):
        rng = np.random.default_rng(seed)
        q0 = np.array([self.coords.get(i).getDefaultValue() for i in range(self.coords.getSize())])
        rows = []
        for _ in range(n):
            q = q0.copy()
            for i in self.free:
                c = self.coords.get(i)
                q[i] = rng.uniform(c.getRangeMin(), c.getRangeMax())
            rows.append(self.complete(q))
        return np.array(rows)

    def write_mot(self, path, q):
        with open(path, "w") as f:
            f.write(f"states\nversion=1\nnRows={len(q)}\nnColumns={len(self.names) + 1}\n"
                    "inDegrees=no\nendheader\n")
            f.write("time\t" + "\t".join(self.names) + "\n")
            for k, row in enumerate(q):
                f.write(f"{0.01 * k:.4f}\t" + "\t".join(f"{v:.17g}" for v in row) + "\n")



def coupler_derivatives(sampler, q):
    """For each coupler: (dependent index, [(independent index, df/dq_i)],
    {(i, j): d²f/dq_i dq_j})."""
    out = []
    for c in sampler.couplers:
        ind = c.getIndependentCoordinateNames()
        idx = [sampler.names.index(ind.get(k)) for k in range(ind.getSize())]
        x = osim.Vector(len(idx), 0.0)
        for k, i in enumerate(idx):
            x.set(k, q[i])
        f = c.getFunction()
        first = [(i, f.calcDerivative(osim.StdVectorInt([k]), x)) for k, i in enumerate(idx)]
        second = {(i, j): f.calcDerivative(osim.StdVectorInt([a, b]), x)
                  for a, i in enumerate(idx) for b, j in enumerate(idx)}
        out.append((sampler.names.index(c.getDependentCoordinateName()), first, second))
    return out


def full_speeds(sampler, full_q, full_qd):
    """full_qd with the coupled coordinates' speeds set from the independent ones (θ̇ = f′q̇)."""
    full_qd = np.array(full_qd, dtype=float)
    for dep, first, _ in coupler_derivatives(sampler, full_q):
        full_qd[dep] = sum(d * full_qd[i] for i, d in first)
    return full_qd


def all_models(work):
    """(label, path) of every .osim under opensim-models, the default model, and the default
    model scaled by `musculo model scale` to 60 kg and 1.60 m (written under `work`)."""
    import glob
    found = sorted(glob.glob(os.path.join(MODELS, "**", "*.osim"), recursive=True))
    out = [(os.path.relpath(p, MODELS), p) for p in found]
    default = os.path.join(REPO, "models", "musculo_fullbody.osim")
    out.append(("models/musculo_fullbody.osim", default))
    scaled = os.path.join(work, "musculo_fullbody_60kg_1.60m.osim")
    os.makedirs(work, exist_ok=True)
    subprocess.run([MUSCULO, "model", "scale", default, "--mass", "60", "--height", "1.60",
                    "-o", scaled], check=True, capture_output=True)
    out.append(("default scaled to 60 kg, 1.60 m", scaled))
    return out


# ---------------------------------------------------------------------------------------------
# Tables


def print_table(headers, rows, file=sys.stdout):
    widths = [max(len(str(h)), *(len(str(r[i])) for r in rows)) if rows else len(str(h))
              for i, h in enumerate(headers)]
    line = "  ".join(str(h).ljust(w) for h, w in zip(headers, widths))
    print(line, file=file)
    print("  ".join("-" * w for w in widths), file=file)
    for r in rows:
        print("  ".join(str(c).rjust(w) if isinstance(c, str) and c[:1] in "-+0123456789."
                        else str(c).ljust(w) for c, w in zip(r, widths)), file=file)


def fmt(x, digits=4):
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "n/a"
    if x == 0:
        return "0"
    if abs(x) >= 1e4 or abs(x) < 1e-3:
        return f"{x:.{digits - 1}e}"
    return f"{x:.{digits}g}"
