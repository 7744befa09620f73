"""Scaling side by side: OpenSim 4.6's ScaleTool against `musculo scale`.

Two cases (CASES): Pipelines/Gait2392_Simbody/subject01_Setup_Scale.xml (the generic model
`gait2392_simbody.osim` is Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim, which
opensim-models installs under that name) and Pipelines/Rajagopal/Scale/scale_setup_run.xml with
Models/Rajagopal/Rajagopal2016.osim. OpenSim's ScaleTool runs on each setup, copied to
target/opensim-validation/scale/setup.xml (scale_rajagopal_run/ for the second) with its inputs
named by paths relative to that folder and its outputs as plain file names; the tool runs
with that folder as working directory (OpenSim 4.6 prefixes the setup's folder to input paths,
absolute ones included, and writes outputs relative to the working directory). It writes
opensim/scaled.osim (after marker placement), opensim/scaled_only.osim and
opensim/scale_set.xml. musculo then scales from the same setup copy (see MUSCULO_SCALE below).

Both scaled models are loaded in OpenSim 4.6 and compared (exit status 1 when one fails):
- per-body scale factors (scale-set files)                                 <= 0.1 %
- body masses                                                              <= 0.1 %
- inertia components, relative to the body's largest moment                <= 0.1 %
- mass centres, joint frame offsets (parent and child), marker locations   <= 1 mm
- coordinate default values                                                 <= 1e-6
- body origins in ground at the generic model's default pose and at 20 random poses  <= 1 mm
- muscle optimal fiber lengths, tendon slack lengths                        <= 0.1 %
- musculotendon lengths, computed by OpenSim for both models, at the generic model's default
  pose and at the same 20 random poses (rotations uniform within the generic model's ranges,
  seed 0; translations at their defaults)                                   <= 0.1 %
The same comparison, for information only, of the stored OutputReference/subject01_simbody.osim
against OpenSim 4.6's result, with the inertia scaling law each follows.

Usage: scale_compare.py [--case gait2392|rajagopal_run]... [--opensim-only] [--self-test]
                        [--musculo-model M.osim
                        [--musculo-scale-set S.xml]]
"""

import argparse
import json
import math
import os
import sys
import time
import xml.etree.ElementTree as ET

import numpy as np

import osimval as ov
from osimval import osim

P = os.path.join(ov.MODELS, "Pipelines")
# The Scale setups compared: each one's generic model, marker set, static trial and the scaled
# model stored beside it (compared with OpenSim 4.6's for information), where there is one.
CASES = {
    "gait2392": dict(
        setup=os.path.join(P, "Gait2392_Simbody", "subject01_Setup_Scale.xml"),
        generic=os.path.join(ov.MODELS, "Models", "Gait2392_Simbody",
                             "gait2392_thelen2003muscle.osim"),
        marker_set=os.path.join(P, "Gait2392_Simbody", "gait2392_Scale_MarkerSet.xml"),
        static=os.path.join(P, "Gait2392_Simbody", "subject01_static.trc"),
        stored=os.path.join(P, "Gait2392_Simbody", "OutputReference", "subject01_simbody.osim"),
        work="scale",
    ),
    "rajagopal_run": dict(
        setup=os.path.join(P, "Rajagopal", "Scale", "scale_setup_run.xml"),
        generic=os.path.join(ov.MODELS, "Models", "Rajagopal", "Rajagopal2016.osim"),
        marker_set=None,
        static=os.path.join(P, "Rajagopal", "ExpData", "static_run.trc"),
        stored=None,
        work="scale_rajagopal_run",
    ),
}

# How musculo is asked to scale (run in the work folder): every output the setup names goes to
# musculo/ under its file name (scaled.osim, scaled_only.osim, scale_set.xml, static_output.mot).
MUSCULO_SCALE = ["scale", "--setup", "setup.xml", "--output-dir", "musculo"]

REL = 1e-3       # 0.1 %
POS = 1e-3       # 1 mm
N_POSES = 20


def prepare(spec):
    """The case's work folder and its setup copy (inputs relative to it, outputs named alike
    for every case)."""
    d = ov.fresh_dir(os.path.join(ov.WORK, spec["work"]))
    for sub in ("opensim", "musculo"):
        os.makedirs(os.path.join(d, sub))
    inputs = [spec["setup"], spec["generic"], spec["static"]]
    inputs += [spec["marker_set"]] if spec["marker_set"] else []
    for path in inputs:
        ov.require(path, "scale input")
    rel = lambda p: os.path.relpath(p, d)  # noqa: E731
    edits = {
        "GenericModelMaker/model_file": rel(spec["generic"]),
        "ModelScaler/marker_file": rel(spec["static"]),
        "ModelScaler/output_model_file": "opensim/scaled_only.osim",
        "ModelScaler/output_scale_file": "opensim/scale_set.xml",
        "MarkerPlacer/marker_file": rel(spec["static"]),
        "MarkerPlacer/output_model_file": "opensim/scaled.osim",
        "MarkerPlacer/output_motion_file": "opensim/static_output.mot",
    }
    if spec["marker_set"]:
        edits["GenericModelMaker/marker_set_file"] = rel(spec["marker_set"])
    setup = ov.edit_setup(spec["setup"], os.path.join(d, "setup.xml"), edits)
    return d, setup


def run_opensim(d, setup):
    log = os.path.join(d, "opensim", "opensim_scale.log")
    osim.Logger.setLevelString("info")
    osim.Logger.addFileSink(log)
    cwd = os.getcwd()
    os.chdir(d)
    try:
        tool = osim.ScaleTool(setup)
        t0 = time.perf_counter()
        ok = tool.run()
        dt = time.perf_counter() - t0
    finally:
        os.chdir(cwd)
        osim.Logger.removeFileSink()
        ov.quiet_opensim()
    if not ok:
        sys.exit(f"OpenSim's ScaleTool failed (see {log})")
    return dt


def read_scale_set(path):
    """{segment: (sx, sy, sz)} from an OpenSim ScaleSet file."""
    out = {}
    for sc in ET.parse(path).getroot().iter("Scale"):
        seg = sc.findtext("segment").strip()
        if sc.findtext("apply", "true").strip().lower() == "true":
            out[seg] = tuple(float(v) for v in sc.findtext("scales").split())
    return out


def poses_of(generic):
    """The generic model's default pose, then N_POSES coordinate vectors (by name): rotations
    uniform within the generic model's ranges, other coordinates at their default values."""
    rng = np.random.default_rng(0)
    coords = generic.getCoordinateSet()
    poses = [{coords.get(i).getName(): coords.get(i).getDefaultValue()
              for i in range(coords.getSize())}]
    for _ in range(N_POSES):
        pose = {}
        for i in range(coords.getSize()):
            c = coords.get(i)
            if c.getMotionType() == osim.Coordinate.Rotational:
                pose[c.getName()] = rng.uniform(c.getRangeMin(), c.getRangeMax())
            else:
                pose[c.getName()] = c.getDefaultValue()
        poses.append(pose)
    return poses


def summary(path, poses):
    """Everything compared, from the model as OpenSim 4.6 loads it."""
    m = osim.Model(path)
    s = m.initSystem()
    out = {"bodies": {}, "joints": {}, "markers": {}, "muscles": {}, "origins": {},
           "mass": m.getTotalMass(s)}
    for b in m.getBodySet():
        inertia = b.get_inertia()
        out["bodies"][b.getName()] = dict(
            mass=b.getMass(), com=b.getMassCenter().to_numpy().copy(),
            inertia=np.array([inertia.get(i) for i in range(6)]))
    for j in m.getJointSet():
        frames = {}
        for k, f in enumerate((j.getParentFrame(), j.getChildFrame())):
            off = osim.PhysicalOffsetFrame.safeDownCast(f)
            frames["parent" if k == 0 else "child"] = (
                off.get_translation().to_numpy().copy() if off else np.zeros(3))
        out["joints"][j.getName()] = frames
    for mk in m.getMarkerSet():
        out["markers"][mk.getName()] = (mk.getParentFrameName(), mk.get_location().to_numpy().copy())
    muscles = m.getMuscles()
    lengths = {muscles.get(i).getName(): [] for i in range(muscles.getSize())}
    coords = m.getCoordinateSet()
    default = {coords.get(i).getName(): coords.get(i).getDefaultValue()
               for i in range(coords.getSize())}
    for p, pose in enumerate(poses):
        for name, v in pose.items():
            if coords.contains(name):
                coords.get(name).setValue(s, float(v), False)
        m.realizeVelocity(s)
        for i in range(muscles.getSize()):
            lengths[muscles.get(i).getName()].append(muscles.get(i).getLength(s))
        for b in m.getBodySet():
            out["origins"].setdefault(b.getName(), []).append(
                b.getTransformInGround(s).p().to_numpy().copy())
    for i in range(muscles.getSize()):
        mu = muscles.get(i)
        out["muscles"][mu.getName()] = dict(
            optimal_fiber_length=mu.getOptimalFiberLength(),
            tendon_slack_length=mu.getTendonSlackLength(),
            mt_length_default=lengths[mu.getName()][0],
            mt_length_poses=np.array(lengths[mu.getName()][1:]))
    out["origins"] = {k: np.array(v) for k, v in out["origins"].items()}
    out["default_pose"] = default
    return out


def rel_diff(a, b):
    return abs(a - b) / max(abs(b), 1e-300)


class Checker:
    """Collects per-quantity worst differences against a tolerance."""

    def __init__(self, label):
        self.label = label
        self.rows = []
        self.failures = []
        self.details = []

    def add(self, quantity, items, tol, unit, enforce=True):
        """items: list of (difference, where); the worst is tabled, the five worst kept."""
        items = sorted(items, key=lambda it: -it[0]) or [(0.0, "-")]
        worst, where = items[0]
        if worst > tol:
            self.details.append((quantity, unit, [it for it in items[:5] if it[0] > tol],
                                 sum(1 for it in items if it[0] > tol), len(items)))
        status = "ok" if worst <= tol else ("FAIL" if enforce else "differs")
        mm = unit == "m"
        self.rows.append([quantity, f"{worst * 1000:.4f}" if mm else f"{worst:.3e}",
                          "mm" if mm else ("relative" if unit == "rel" else "rad or m"),
                          f"{tol * 1000:g}" if mm else f"{tol:g}", where, status])
        if enforce and worst > tol:
            self.failures.append(f"{quantity}: {worst:.3e} at {where}")

    def print(self):
        print(f"\n{self.label}")
        ov.print_table(["quantity", "worst", "unit", "tolerance", "where", "status"], self.rows)
        for quantity, unit, top, count, total in self.details:
            shown = ", ".join(f"{w} {v * 1000:.2f} mm" if unit == "m" else f"{w} {v:.3e}"
                              for v, w in top)
            print(f"  {quantity}: {count}/{total} over tolerance; worst: {shown}")


def compare(a, b, label, enforce=True, scale_a=None, scale_b=None, placed=None):
    """Compares summary a (candidate) with summary b (OpenSim 4.6).

    placed: marker locations from OpenSim's placement at its converged static pose; when given,
    the marker check is against those (the ScaleTool's own are shown for information)."""
    ck = Checker(label)
    missing = []
    for group in ("bodies", "joints", "markers", "muscles"):
        for name in b[group]:
            if name not in a[group]:
                missing.append(f"{group[:-1]} {name}")
    if missing:
        ck.failures.append(f"missing in candidate: {', '.join(missing[:10])}"
                           + (f" and {len(missing) - 10} more" if len(missing) > 10 else ""))
    bodies = [n for n in b["bodies"] if n in a["bodies"]]
    if scale_a is not None and scale_b is not None:
        items = [(max(rel_diff(x, y) for x, y in zip(scale_a[s], scale_b[s])), s)
                 for s in scale_b if s in scale_a]
        absent = [s for s in scale_b if s not in scale_a]
        if absent:
            ck.failures.append(f"scale factors missing for {absent}")
        ck.add("scale factors", list(items), REL, "rel", enforce)
    ck.add("total mass", [(rel_diff(a["mass"], b["mass"]), "model")], REL, "rel", enforce)
    ck.add("coordinate default values (rad or m)", [
        (abs(a["default_pose"][n] - v), n) for n, v in b["default_pose"].items()
        if n in a["default_pose"]], 1e-6, "abs", enforce)
    ck.add("body mass", list((rel_diff(a["bodies"][n]["mass"], b["bodies"][n]["mass"]), n)
                                  for n in bodies), REL, "rel", enforce)
    ck.add("inertia", list(
        (np.max(np.abs(a["bodies"][n]["inertia"] - b["bodies"][n]["inertia"]))
         / max(np.max(np.abs(b["bodies"][n]["inertia"][:3])), 1e-300), n)
        for n in bodies if b["bodies"][n]["mass"] > 0), REL, "rel", enforce)
    ck.add("mass centre", list(
        (np.linalg.norm(a["bodies"][n]["com"] - b["bodies"][n]["com"]), n) for n in bodies),
        POS, "m", enforce)
    joints = [n for n in b["joints"] if n in a["joints"]]
    ck.add("joint frame offsets", list(
        (np.linalg.norm(a["joints"][n][k] - b["joints"][n][k]), f"{n} {k}")
        for n in joints for k in ("parent", "child")), POS, "m", enforce)
    markers = [n for n in b["markers"] if n in a["markers"]]
    wrong_body = [n for n in markers if a["markers"][n][0] != b["markers"][n][0]]
    if wrong_body:
        ck.failures.append(f"markers on other bodies: {wrong_body}")
    ck.add("marker locations" + (" (vs ScaleTool output)" if placed else ""), list(
        (np.linalg.norm(a["markers"][n][1] - b["markers"][n][1]), n) for n in markers),
        POS, "m", enforce and placed is None)
    if placed:
        ck.add("marker locations (vs OpenSim placed at acc. 1e-9)", list(
            (np.linalg.norm(a["markers"][n][1] - placed[n][1]), n) for n in markers
            if n in placed), POS, "m", enforce)
    ck.add("body origins in ground (default + 20 poses)", list(
        (float(np.max(np.linalg.norm(a["origins"][n] - b["origins"][n], axis=1))), n)
        for n in bodies), POS, "m", enforce)
    muscles = [n for n in b["muscles"] if n in a["muscles"]]
    for q in ("optimal_fiber_length", "tendon_slack_length", "mt_length_default"):
        ck.add(q.replace("_", " "), list(
            (rel_diff(a["muscles"][n][q], b["muscles"][n][q]), n) for n in muscles),
            REL, "rel", enforce)
    ck.add("mt length (20 poses)", list(
        (float(np.max(np.abs(a["muscles"][n]["mt_length_poses"] - b["muscles"][n]["mt_length_poses"])
                      / b["muscles"][n]["mt_length_poses"])), n) for n in muscles),
        REL, "rel", enforce)
    ck.print()
    for f in ck.failures:
        print(f"{'FAIL' if enforce else 'note'}: {f}")
    return ck


class Placer:
    """OpenSim's MarkerPlacer step, redone in OpenSim with a chosen accuracy.

    As MarkerPlacer::processModel in 4.6: the static trial's markers averaged over the time
    range (TimeSeriesTable::averageRow), converted to metres; marker weights from the placer's
    IKTaskSet; coordinate tasks (default value = the coordinate's value in the default state,
    manual value as is); one InverseKinematicsSolver::assemble from the default pose of the
    scaled-only model; then every non-fixed marker observed in the trial is moved onto its
    averaged observation, expressed in its own body frame. OpenSim's tool leaves the solver at
    the AssemblySolver's default accuracy (1e-4).
    """

    def __init__(self, setup, scaled_only, static):
        tool = osim.ScaleTool(setup)
        placer = tool.getMarkerPlacer()
        tasks = placer.getIKTaskSet()
        time_range = placer.getTimeRange()
        self.t0, t1 = time_range.get(0), time_range.get(1)
        table = osim.TimeSeriesTableVec3(static)
        # where markers move to: MarkerData::averageFrames, which skips missing samples (the
        # IK targets below are averageRow's, missing wherever one sample is)
        times = np.array(table.getIndependentColumn())
        rows = [r for r, t in enumerate(times) if self.t0 <= t <= t1]
        unit = 1e-3 if table.getTableMetaDataAsString("Units").strip().lower() == "mm" else 1.0
        labels = table.getColumnLabels()
        self.window_mean = {}
        for k, label in enumerate(labels):
            col = table.getDependentColumnAtIndex(k)
            samples = np.array([col[r].to_numpy() for r in rows]) * unit
            present = samples[np.all(np.isfinite(samples), axis=1)]
            if len(present):
                self.window_mean[label] = present.mean(axis=0)
        avg = table.averageRow(self.t0, t1)
        for r in range(table.getNumRows() - 1, -1, -1):
            table.removeRowAtIndex(r)
        table.appendRow(self.t0, avg)
        self.model = osim.Model(scaled_only)
        self.state = self.model.initSystem()
        weights = osim.SetMarkerWeights()
        tasks.createMarkerWeightSet(weights)
        self.ref = osim.MarkersReference(table, weights)
        coords = self.model.getCoordinateSet()
        self.names = [coords.get(i).getName() for i in range(coords.getSize())]
        self.coord_refs = osim.SimTKArrayCoordinateReference()
        self.coord_tasks = []
        for i in range(tasks.getSize()):
            task = tasks.get(i)
            if task.getConcreteClassName() != "IKCoordinateTask" or not task.getApply():
                continue
            ct = osim.IKCoordinateTask.safeDownCast(task)
            if ct.getValueType() == osim.IKCoordinateTask.FromFile:
                sys.exit("MarkerPlacer coordinate tasks from a file are not handled")
            value = (ct.getValue() if ct.getValueType() == osim.IKCoordinateTask.ManualValue
                     else coords.get(ct.getName()).getValue(self.state))
            ref = osim.CoordinateReference(ct.getName(), osim.Constant(value))
            ref.setWeight(ct.getWeight())
            self.coord_refs.push_back(ref)
            self.coord_tasks.append((self.names.index(ct.getName()), ct.getWeight(), value))
        names = self.ref.getNames()
        w = osim.SimTKArrayDouble()
        self.ref.getWeights(self.state, w)
        vals = osim.SimTKArrayVec3()
        self.ref.getValuesAtTime(self.t0, vals)
        mset = self.model.getMarkerSet()
        self.markers = [(names.getElt(j), w.getElt(j), vals.getElt(j).to_numpy().copy())
                        for j in range(names.size()) if mset.contains(names.getElt(j))]

    def set_pose(self, q):
        coords = self.model.getCoordinateSet()
        for n, v in zip(self.names, q):
            coords.get(n).setValue(self.state, float(v), False)
        self.model.realizePosition(self.state)

    def objective(self, q):
        """IK objective of the placer (as ik_compare.py's F) and OpenSim's total squared error."""
        self.set_pose(q)
        mset = self.model.getMarkerSet()
        num = wsum = tse = 0.0
        for n, w, obs in self.markers:
            if not np.all(np.isfinite(obs)):
                continue
            e2 = float(np.sum((mset.get(n).getLocationInGround(self.state).to_numpy() - obs) ** 2))
            num += w * e2
            wsum += w
            tse += e2
        f = num / (2 * wsum)
        for k, w, value in self.coord_tasks:
            f += 0.5 * w * (q[k] - value) ** 2
        return f, tse

    def solve(self, accuracy):
        state = self.model.initSystem()
        state.setTime(self.t0)
        solver = osim.InverseKinematicsSolver(self.model, self.ref, self.coord_refs, math.inf)
        solver.setAccuracy(accuracy)
        solver.assemble(state)
        coords = self.model.getCoordinateSet()
        q = np.array([coords.get(n).getValue(state) for n in self.names])
        self.state = state
        return q

    def place(self, q):
        """{marker: (body path, location)} after moving the markers at pose q."""
        self.set_pose(q)
        ground = self.model.getGround()
        out = {}
        for mk in self.model.getMarkerSet():
            loc = mk.get_location().to_numpy().copy()
            obs = self.window_mean.get(mk.getName())
            if not mk.get_fixed() and obs is not None:
                loc = ground.findStationLocationInAnotherFrame(
                    self.state, osim.Vec3(*obs), mk.getParentFrame()).to_numpy().copy()
            out[mk.getName()] = (mk.getParentFrameName(), loc)
        return out

    def pose_of(self, mot):
        _, cols = ov.read_motion(mot, self.model)
        return np.array([float(cols[n][0]) for n in self.names])


def opensim_placement(d, setup, static):
    """OpenSim's placer redone at accuracy 1e-4 (as the tool) and 1e-9; returns
    (placer, F of the tool's pose, converged pose, converged placement, report)."""
    placer = Placer(setup, os.path.join(d, "opensim", "scaled_only.osim"), static)
    q_os = placer.pose_of(os.path.join(d, "opensim", "static_output.mot"))
    q_loose = placer.solve(1e-4)
    q_tight = placer.solve(1e-9)
    f_os, tse_os = placer.objective(q_os)
    f_tight, _ = placer.objective(q_tight)
    n = len(placer.markers)
    print(f"\nmarker placer (static pose at t = {placer.t0:g} s, {n} markers): OpenSim's tool F = "
          f"{f_os:.6e} (RMS {1000 * math.sqrt(tse_os / n):.2f} mm); redone here at accuracy 1e-4: "
          f"pose within {np.max(np.abs(q_loose - q_os)) * ov.DEG:.1e} deg of the tool's; at "
          f"accuracy 1e-9: F = {f_tight:.6e} ({(f_tight / f_os - 1) * 100:+.4f} %), pose "
          f"{np.max(np.abs(q_tight - q_os)) * ov.DEG:.3f} deg from the tool's "
          f"({placer.names[int(np.argmax(np.abs(q_tight - q_os)))]})")
    rep = dict(f_opensim=f_os, f_opensim_tight=f_tight,
               tight_vs_tool_deg=float(np.max(np.abs(q_tight - q_os)) * ov.DEG))
    return placer, f_os, q_tight, placer.place(q_tight), rep


def musculo_static(placer, f_os, q_tight, mu_static, rep):
    """musculo's static pose judged on the placer's objective; returns failures."""
    n = len(placer.markers)
    failures = []
    if mu_static:
        q_mu = placer.pose_of(mu_static)
        f_mu, tse_mu = placer.objective(q_mu)
        k = int(np.argmax(np.abs(q_mu - q_tight)))
        print(f"musculo's static pose: F = {f_mu:.6e} (F/F(OpenSim's tool) = {f_mu / f_os:.6f}, "
              f"RMS {1000 * math.sqrt(tse_mu / n):.2f} mm); "
              f"{np.max(np.abs(q_mu - q_tight)) * ov.DEG:.2e} deg from OpenSim's converged pose "
              f"({placer.names[k]})")
        rep.update(f_musculo=f_mu, musculo_vs_tight_deg=float(np.max(np.abs(q_mu - q_tight)) * ov.DEG))
        if f_mu > f_os * 1.001 + 1e-9:
            failures.append(f"static-pose objective {f_mu / f_os:.6f} x OpenSim's")
    return failures


def inertia_law(generic, stored, scaled46, scale46):
    """Per body: mass ratio, inertia ratio of the stored model and of OpenSim 4.6's, and the
    ratio 4.6's rule predicts for a uniform scale s: (m'/m) s^2."""
    rows = []
    out = {}
    for n, g in generic["bodies"].items():
        if g["mass"] == 0 or n not in stored["bodies"]:
            continue
        gi = g["inertia"][:3]
        k = int(np.argmax(gi))
        st, os46 = stored["bodies"][n], scaled46["bodies"][n]
        s = scale46.get(n, (1, 1, 1))
        r_mass_st = st["mass"] / g["mass"]
        r_mass_46 = os46["mass"] / g["mass"]
        r_i_st = st["inertia"][k] / gi[k]
        r_i_46 = os46["inertia"][k] / gi[k]
        rows.append([n, f"{s[0]:.5f}", f"{r_mass_st:.5f}", f"{r_mass_46:.5f}", f"{r_i_st:.5f}",
                     f"{r_i_46:.5f}", f"{r_mass_46 * s[0] ** 2:.5f}",
                     f"{(st['inertia'][k] - os46['inertia'][k]) / os46['inertia'][k] * 100:+.2f}"])
        out[n] = dict(scale=s[0], mass_ratio_stored=r_mass_st, mass_ratio_46=r_mass_46,
                      inertia_ratio_stored=r_i_st, inertia_ratio_46=r_i_46)
    print("\ninertia scaling (largest moment of each body; ratios to the generic model):")
    ov.print_table(["body", "scale s", "mass ratio stored", "mass ratio 4.6", "I ratio stored",
                    "I ratio 4.6", "(m'/m) s^2", "stored vs 4.6 %"], rows)
    return out


def muscle_scaling(generic, stored, scaled46):
    """Whether the stored model's fiber and tendon lengths were scaled at all."""
    out = {}
    for q in ("optimal_fiber_length", "tendon_slack_length"):
        names = [n for n in generic["muscles"] if n in stored["muscles"]]
        same = [n for n in names
                if rel_diff(stored["muscles"][n][q], generic["muscles"][n][q]) < 1e-9]
        r46 = np.array([scaled46["muscles"][n][q] / generic["muscles"][n][q] for n in names])
        out[q] = dict(unscaled_in_stored=len(same), muscles=len(names),
                      ratio_46_min=float(r46.min()), ratio_46_max=float(r46.max()))
        print(f"{q.replace('_', ' ')}: the stored model keeps the generic value for {len(same)}"
              f"/{len(names)} muscles; OpenSim 4.6 scales it by {r46.min():.4f} to "
              f"{r46.max():.4f} (its musculotendon-length ratio at the default pose)")
    return out


def static_pose(model_path, os_mot, mu_mot):
    """Information: the marker placer's static pose (an IK frame), musculo against OpenSim."""
    model = osim.Model(model_path)
    _, a = ov.read_motion(os_mot, model)
    _, b = ov.read_motion(mu_mot, model)
    rows, out = [], {}
    for c in model.getCoordinateSet():
        n = c.getName()
        if n in a and n in b:
            scale, unit, _ = ov.coordinate_unit(c)
            diff = abs(float(a[n][0]) - float(b[n][0])) * scale
            rows.append([n, unit, f"{float(a[n][0]) * scale:.4f}", f"{float(b[n][0]) * scale:.4f}",
                         f"{diff:.4f}"])
            out[n] = diff
    print("\nmarker placer's static pose (information):")
    ov.print_table(["coordinate", "unit", "OpenSim", "musculo", "|diff|"], rows)
    return out


def run_musculo_scale(d, args):
    """Runs `musculo scale` in the work folder; returns (model path, scale-set path or None)."""
    if args.musculo_model:
        return args.musculo_model, args.musculo_scale_set
    if not ov.musculo_has("scale"):
        print("musculo scale: not available in target/release/musculo")
        return None, None
    cwd = os.getcwd()
    os.chdir(d)
    try:
        ok, secs, out = ov.run_musculo(MUSCULO_SCALE, os.path.join(d, "musculo", "musculo_scale.log"))
    finally:
        os.chdir(cwd)
    if not ok:
        print(out[-3000:])
        return None, None
    print(f"musculo scale: {secs:.3f} s (whole process)")
    model = os.path.join(d, "musculo", "scaled.osim")
    scale = os.path.join(d, "musculo", "scale_set.xml")
    return model, scale if os.path.exists(scale) else None


def compare_case(case, spec, args):
    """Runs one Scale setup through OpenSim 4.6 and musculo; returns the case's report."""
    print(f"=== Scale {case}: {os.path.relpath(spec['setup'], ov.MODELS)}")
    d, setup = prepare(spec)
    seconds = run_opensim(d, setup)
    print(f"OpenSim 4.6 ScaleTool: {seconds:.3f} s (tool.run: load, scale, place markers, write)")
    os_model = os.path.join(d, "opensim", "scaled.osim")
    scale46 = read_scale_set(os.path.join(d, "opensim", "scale_set.xml"))
    generic_model = osim.Model(spec["generic"])
    poses = poses_of(generic_model)
    s46 = summary(os_model, poses)
    report = dict(seconds=seconds, failures=[])

    placer, f_placer, q_tight, placed, report["placer"] = opensim_placement(
        d, setup, spec["static"])
    if spec["stored"]:
        stored = summary(spec["stored"], poses)
        ck = compare(stored, s46, f"stored {os.path.relpath(spec['stored'], ov.MODELS)} vs "
                     "OpenSim 4.6 (information; tolerances as for musculo)", enforce=False,
                     placed=placed)
        report["stored"] = {r[0]: r[1] for r in ck.rows}
        generic = summary(spec["generic"], poses)
        report["inertia_law"] = inertia_law(generic, stored, s46, scale46)
        report["muscle_scaling"] = muscle_scaling(generic, stored, s46)

    if args.self_test:
        cand, cand_scale = os_model, os.path.join(d, "opensim", "scale_set.xml")
        print("\nself-test: OpenSim's own scaled model stands in for musculo's")
    elif args.opensim_only:
        cand, cand_scale = None, None
    else:
        cand, cand_scale = run_musculo_scale(d, args)
        if cand is None:
            report["failures"].append("musculo scale did not run")
    if cand:
        smu = summary(cand, poses)
        static = os.path.join(os.path.dirname(cand), "static_output.mot")
        report["failures"] += musculo_static(
            placer, f_placer, q_tight,
            static if os.path.exists(static) and not args.self_test else None, report["placer"])
        ck = compare(smu, s46, "musculo's scaled model (loaded in OpenSim 4.6) vs OpenSim 4.6's",
                     scale_a=read_scale_set(cand_scale) if cand_scale else None, scale_b=scale46,
                     placed=None if args.self_test else placed)
        if not cand_scale:
            print("note: no scale-set file from musculo; scale factors compared through the "
                  "model quantities only")
        report["musculo"] = {r[0]: r[1] for r in ck.rows}
        report["failures"] += ck.failures
        if os.path.exists(static) and not args.self_test:
            report["static_pose"] = static_pose(os_model, os.path.join(d, "opensim",
                                                                      "static_output.mot"), static)
    for f in report["failures"]:
        print(f"FAIL {case}: {f}")
    return report


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", action="append", choices=sorted(CASES))
    ap.add_argument("--opensim-only", action="store_true")
    ap.add_argument("--self-test", action="store_true",
                    help="compare OpenSim's scaled model with itself (checks this script)")
    ap.add_argument("--musculo-model")
    ap.add_argument("--musculo-scale-set")
    args = ap.parse_args()
    ov.quiet_opensim()
    cases = args.case or sorted(CASES)
    if args.musculo_model and len(cases) != 1:
        sys.exit("--musculo-model needs one --case")
    report = {case: compare_case(case, CASES[case], args) for case in cases}
    with open(os.path.join(ov.WORK, "scale_report.json"), "w", encoding="utf-8") as f:
        json.dump(report, f, indent=1, default=float)
    ok = not any(r["failures"] for r in report.values())
    print(f"\nScale side by side: {'PASS' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
