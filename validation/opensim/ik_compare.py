"""Inverse kinematics side by side: OpenSim 4.6's InverseKinematicsTool against `musculo ik`.

For each case (an OpenSim IK setup from the reference pipelines, copied with absolute paths to
target/opensim-validation/ik_<case>/setup.xml), OpenSim's tool runs on the copy (timed), then
`musculo ik --setup <copy> -o .../musculo/musculo_ik.mot` runs on the same copy. Both solutions
are then judged by OpenSim itself, frame by frame, on the objective OpenSim minimises:

    F(q) = sum_i w_i |x_i(q) - m_i|^2 / (2 sum_i w_i)  +  1/2 sum_j w_j (q_j - r_j)^2

i over the IKMarkerTasks that apply, whose marker is in the model and observed (finite) in that
frame (weights w_i from the setup); j over the IKCoordinateTasks that apply, except coordinates
that are locked (OpenSim locks them instead) or free to satisfy constraints; r_j the task's
default value, manual value (taken as is, in model units) or the coordinate file's GCV spline.
That is Simbody's Assembler objective for the Markers goal (weight 1) plus one QValue goal per
coordinate task (weight w_j), as OpenSim 4.6's InverseKinematicsSolver sets them up. x_i(q) are
OpenSim's marker locations in ground after setting the coordinates and realising Position; m_i
is the experimental marker at the frame's time (MarkersReference, converted to metres).

Checks (exit status 1 when one fails):
- per frame F(musculo) <= F(OpenSim) * 1.001 + 1e-9;
- per coordinate, |q_musculo - q_OpenSim| <= 0.5 deg (rotational) / 2 mm (others) at frames
  where the coordinate is well determined: moving it by that tolerance, with the others
  re-optimised, raises F by more than 0.01 % (Gauss-Newton Hessian H of F from OpenSim's
  marker Jacobians by central differences; the rise is tol^2 / (2 (H^-1)_kk));
- musculo's .mot has the same frames and coordinates as OpenSim's, locked coordinates at their
  default values, and its _ik_marker_errors.sto agrees with OpenSim's evaluation of its .mot.

Also printed: OpenSim's timing; how OpenSim's own total_squared_error column compares with this
evaluator at OpenSim's solution (a check of the evaluator); OpenSim run again at accuracy 1e-9
(how far its default run is from its own optimum, and musculo's distance to that); and how the
.mot files stored in the reference folders differ from OpenSim 4.6's run.

Usage: ik_compare.py [--case gait2392|gait10dof|rajagopal_run]... [--full-trial] [--musculo-mot CASE=FILE]... [--self-test]
  --self-test   feed OpenSim's own .mot as "musculo's" (checks the comparison code itself)
  --opensim-only   run and evaluate OpenSim only
"""

import argparse
import json
import math
import os
import sys
import time

import numpy as np

import osimval as ov
from osimval import osim

P = os.path.join(ov.MODELS, "Pipelines")
CASES = {
    "gait2392": dict(
        setup=os.path.join(P, "Gait2392_Simbody", "subject01_Setup_IK.xml"),
        model=os.path.join(P, "Gait2392_Simbody", "OutputReference", "subject01_simbody.osim"),
        markers=os.path.join(P, "Gait2392_Simbody", "subject01_walk1.trc"),
        stored=[os.path.join(P, "Gait2392_Simbody", "subject01_walk1_ik.mot"),
                os.path.join(P, "Gait2392_Simbody", "OutputReference", "subject01_walk1_ik.mot")],
    ),
    "gait10dof": dict(
        setup=os.path.join(P, "Gait10dof18musc", "IK", "walk_Setup_IK.xml"),
        model=os.path.join(P, "Gait10dof18musc", "OutputReference", "subject01.osim"),
        markers=os.path.join(P, "Gait10dof18musc", "ExperimentalData", "subject01_walk.trc"),
        stored=[os.path.join(P, "Gait10dof18musc", "OutputReference", "IK",
                             "subject01_walk_IK.mot")],
    ),
    # The Rajagopal running trial on the model OpenSim 4.6's ScaleTool makes from the
    # pipeline's Scale setup (scale_compare.py's rajagopal_run case; run here if absent).
    "rajagopal_run": dict(
        setup=os.path.join(P, "Rajagopal", "IK", "ik_setup_run.xml"),
        model=os.path.join(ov.WORK, "scale_rajagopal_run", "opensim", "scaled.osim"),
        markers=os.path.join(P, "Rajagopal", "ExpData", "motion_capture_run.trc"),
        stored=[],
        scaled_by="rajagopal_run",
        # 150 of the trial's 510 frames (three strides) keep CI's time; --full-trial runs all
        time_range="0.23 1.72",
    ),
}

OBJECTIVE_RATIO = 1.001
OBJECTIVE_ABS = 1e-9
# A coordinate is well determined at a frame when moving it by its tolerance (others
# re-optimised) raises F by more than this fraction of F: ten times below the objective
# tolerance, three times above the gap between OpenSim at accuracy 1e-5 and at 1e-9 (3e-5 on
# gait2392).
WELL_DETERMINED_REL = 1e-4
TIGHT_ACCURACY = "1e-9"
FD_STEP = 1e-6


class Problem:
    """OpenSim's IK problem for one setup: model, marker and coordinate references, weights."""

    def __init__(self, setup):
        tool = osim.InverseKinematicsTool(setup, False)
        self.model = osim.Model(tool.get_model_file())
        # Locked coordinates must still take the values a .mot gives them in evaluation.
        self.locked = set()
        for c in self.model.getCoordinateSet():
            if c.getDefaultLocked():
                self.locked.add(c.getName())
                c.setDefaultLocked(False)
        self.state = self.model.initSystem()
        coords = self.model.getCoordinateSet()
        self.coord_names = [coords.get(i).getName() for i in range(coords.getSize())]
        self.coords = [coords.get(n) for n in self.coord_names]
        self.defaults = np.array([c.getDefaultValue() for c in self.coords])

        # Tasks, as InverseKinematicsTool::populateReferences reads them.
        weights = osim.SetMarkerWeights()
        self.coord_tasks = []  # (index, weight, kind, value-or-spline)
        self.dropped_tasks = []
        splines = None
        cfile = tool.get_coordinate_file()
        if cfile not in ("", "Unassigned"):
            sto = osim.Storage(cfile)
            self.model.getSimbodyEngine().convertDegreesToRadians(sto)
            splines = osim.GCVSplineSet(5, sto)
        tasks = tool.getIKTaskSet()
        for i in range(tasks.getSize()):
            task = tasks.get(i)
            if not task.getApply():
                continue
            if task.getConcreteClassName() == "IKMarkerTask":
                weights.cloneAndAppend(osim.MarkerWeight(task.getName(), task.getWeight()))
                continue
            ctask = osim.IKCoordinateTask.safeDownCast(task)
            name = ctask.getName()
            if name not in self.coord_names:
                sys.exit(f"{setup}: coordinate task {name} names no model coordinate")
            k = self.coord_names.index(name)
            if name in self.locked or coords.get(name).get_is_free_to_satisfy_constraints():
                self.dropped_tasks.append(name)
                continue
            vt = ctask.getValueType()
            if vt == osim.IKCoordinateTask.FromFile:
                if splines is None or not splines.contains(name):
                    sys.exit(f"{setup}: no coordinate_file values for task {name}")
                self.coord_tasks.append((k, ctask.getWeight(), "file", splines.get(name)))
            elif vt == osim.IKCoordinateTask.ManualValue:
                self.coord_tasks.append((k, ctask.getWeight(), "manual", ctask.getValue()))
            else:
                self.coord_tasks.append((k, ctask.getWeight(), "default", self.defaults[k]))
        self.markers_ref = osim.MarkersReference()
        self.markers_ref.initializeFromMarkersFile(tool.get_marker_file(), weights)
        names = self.markers_ref.getNames()
        ref_names = [names.getElt(i) for i in range(names.size())]
        ref_w = osim.SimTKArrayDouble()
        self.markers_ref.getWeights(self.state, ref_w)
        mset = self.model.getMarkerSet()
        self.marker_names, self.marker_w, self.ref_index, self.markers = [], [], [], []
        for j, n in enumerate(ref_names):
            if mset.contains(n):
                self.marker_names.append(n)
                self.marker_w.append(ref_w.getElt(j))
                self.ref_index.append(j)
                self.markers.append(mset.get(n))
        self.marker_w = np.array(self.marker_w)
        self.constraint_weight = tool.get_constraint_weight()
        if self.model.getConstraintSet().getSize() and math.isfinite(self.constraint_weight):
            sys.exit("models with constraints weighted into the objective are not handled")
        self.time_range = (tool.get_time_range(0), tool.get_time_range(1))

    # -- evaluation -------------------------------------------------------------------------
    def observed(self, t):
        vals = osim.SimTKArrayVec3()
        self.markers_ref.getValuesAtTime(t, vals)
        return np.array([vals.getElt(j).to_numpy() for j in self.ref_index])

    def locations(self, q):
        for c, v in zip(self.coords, q):
            c.setValue(self.state, float(v), False)
        self.model.realizePosition(self.state)
        return np.array([m.getLocationInGround(self.state).to_numpy() for m in self.markers])

    def coord_targets(self, t):
        out = []
        for k, w, kind, val in self.coord_tasks:
            if kind == "file":
                val = val.calcValue(osim.Vector(1, t))
            out.append((k, w, val))
        return out

    def objective(self, q, t, obs=None):
        """(F, unweighted total squared marker error, per-marker squared errors, present mask)."""
        obs = self.observed(t) if obs is None else obs
        x = self.locations(q)
        present = np.all(np.isfinite(obs), axis=1)
        e2 = np.where(present, np.sum((x - np.where(present[:, None], obs, 0.0)) ** 2, axis=1),
                      0.0)
        wsum = self.marker_w[present].sum()
        f = float(np.sum(self.marker_w * e2) / (2 * wsum)) if wsum > 0 else 0.0
        self.last_marker_term = f
        for k, w, r in self.coord_targets(t):
            f += 0.5 * w * (q[k] - r) ** 2
        return f, float(e2.sum()), e2, present

    def gauss_newton_hessian(self, q, t, obs=None):
        """H = J^T W J / sum(w) + diag(coordinate task weights), J by central differences."""
        obs = self.observed(t) if obs is None else obs
        present = np.all(np.isfinite(obs), axis=1)
        n = len(q)
        jac = np.zeros((len(self.markers), 3, n))
        for k in range(n):
            qp, qm = q.copy(), q.copy()
            qp[k] += FD_STEP
            qm[k] -= FD_STEP
            jac[:, :, k] = (self.locations(qp) - self.locations(qm)) / (2 * FD_STEP)
        w = np.where(present, self.marker_w, 0.0)
        h = np.einsum("m,mak,mal->kl", w, jac, jac) / w.sum()
        for k, wt, _ in self.coord_targets(t):
            h[k, k] += wt
        return h


def motion_matrix(problem, path):
    """(times, q matrix frames x model coordinates, missing coordinate names)."""
    times, cols = ov.read_motion(path, problem.model)
    q = np.tile(problem.defaults, (len(times), 1))
    missing = []
    for k, n in enumerate(problem.coord_names):
        if n in cols:
            q[:, k] = cols[n]
        else:
            missing.append(n)
    return times, q, missing


def run_opensim(case, setup, outdir, log_name="opensim_ik.log"):
    """Runs OpenSim's IK tool on the setup copy.

    Returns (seconds for tool.run, seconds per frame between the first and the last frame's
    log lines: the tracking loop alone)."""
    log = os.path.join(outdir, log_name)
    osim.Logger.setLevelString("info")
    osim.Logger.addFileSink(log)
    # The console sink would print a line per frame: silence fd 1 during the run.
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    try:
        tool = osim.InverseKinematicsTool(setup)
        t0 = time.perf_counter()
        ok = tool.run()
        dt = time.perf_counter() - t0
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(devnull)
        os.close(saved)
        osim.Logger.removeFileSink()
        ov.quiet_opensim()
    if not ok:
        sys.exit(f"{case}: OpenSim's InverseKinematicsTool failed (see {log})")
    stamps = []
    for ln in open(log, encoding="utf-8"):
        if "] Frame " in ln:
            clock = ln[1:ln.index("]")].split()[1]
            h, m, sec = clock.split(":")
            stamps.append(3600 * int(h) + 60 * int(m) + float(sec))
    per_frame = (stamps[-1] - stamps[0]) / (len(stamps) - 1) if len(stamps) > 1 else float("nan")
    return dt, per_frame


def scaled_model(spec):
    """Runs OpenSim's ScaleTool for a case whose model it makes, unless already made."""
    if spec.get("scaled_by") and not os.path.exists(spec["model"]):
        import scale_compare
        d, setup = scale_compare.prepare(scale_compare.CASES[spec["scaled_by"]])
        scale_compare.run_opensim(d, setup)


def prepare(case, spec, full_trial=False):
    scaled_model(spec)
    d = os.path.join(ov.WORK, f"ik_{case}")
    ov.fresh_dir(d)
    os.makedirs(os.path.join(d, "opensim"))
    os.makedirs(os.path.join(d, "musculo"))
    for key in ("setup", "model", "markers"):
        ov.require(spec[key], f"{case} {key}")
    edits = {
        "model_file": spec["model"],
        "marker_file": spec["markers"],
        "results_directory": os.path.join(d, "opensim"),
        "output_motion_file": os.path.join(d, "opensim", "opensim_ik.mot"),
    }
    if spec.get("time_range") and not full_trial:
        edits["time_range"] = spec["time_range"]
    setup = ov.edit_setup(spec["setup"], os.path.join(d, "setup.xml"), edits)
    return d, setup


def evaluate(problem, times, q):
    """Per frame: F, total squared error, GN Hessian diag of inverse, per-marker errors."""
    f = np.zeros(len(times))
    tse = np.zeros(len(times))
    for i, t in enumerate(times):
        f[i], tse[i], _, _ = problem.objective(q[i], t)
    return f, tse


def compare_case(case, spec, args, report):
    print(f"\n=== IK {case}: {os.path.relpath(spec['setup'], ov.MODELS)}")
    d, setup = prepare(case, spec, args.full_trial)
    seconds, per_frame = run_opensim(case, setup, os.path.join(d, "opensim"))
    problem = Problem(setup)
    os_mot = os.path.join(d, "opensim", "opensim_ik.mot")
    times, q_os, _ = motion_matrix(problem, os_mot)
    n = len(times)
    print(f"OpenSim 4.6 IK: {n} frames, tool.run {seconds:.3f} s ({1000 * seconds / n:.2f} "
          f"ms/frame incl. model load); tracking loop {1000 * per_frame:.2f} ms/frame "
          f"(from its log's time stamps)")
    print(f"markers in the objective: {len(problem.marker_names)} "
          f"(sum of weights {problem.marker_w.sum():g}); coordinate tasks in it: "
          f"{[problem.coord_names[k] for k, *_ in problem.coord_tasks]}; "
          f"tasks dropped (locked coordinates): {problem.dropped_tasks}")

    f_os, tse_os = evaluate(problem, times, q_os)
    errs = [p for p in os.listdir(os.path.join(d, "opensim")) if p.endswith("_ik_marker_errors.sto")]
    res = dict(frames=n, seconds=seconds, ms_per_frame=1000 * seconds / n,
               ms_per_frame_loop=1000 * per_frame,
               objective_opensim=f_os.tolist(), times=times.tolist(), failures=[])
    if errs:
        et, ecols = ov.read_sto_columns(os.path.join(d, "opensim", errs[0]))
        rel = np.abs(tse_os - ecols["total_squared_error"]) / np.maximum(
            ecols["total_squared_error"], 1e-300)
        print(f"evaluator check: OpenSim's total_squared_error vs this evaluator at OpenSim's "
              f"solution: max rel. diff {rel.max():.2e} (the .mot's 8 decimals limit it)")
        res["evaluator_rel_diff"] = float(rel.max())
        if rel.max() > 1e-5:
            res["failures"].append(f"evaluator disagrees with OpenSim's marker errors ({rel.max():.2e})")
        res["opensim_rms"] = ecols["marker_error_RMS"].tolist()
        res["opensim_total_squared_error"] = ecols["total_squared_error"].tolist()
    print(f"OpenSim objective F per frame: min {f_os.min():.4e}, median {np.median(f_os):.4e}, "
          f"max {f_os.max():.4e}")

    # OpenSim again at a tight accuracy: how far is its default run from its own optimum?
    tight_setup = ov.edit_setup(setup, os.path.join(d, "setup_tight.xml"), {
        "accuracy": TIGHT_ACCURACY,
        "results_directory": os.path.join(d, "opensim_tight"),
        "output_motion_file": os.path.join(d, "opensim_tight", "opensim_ik.mot")})
    os.makedirs(os.path.join(d, "opensim_tight"))
    run_opensim(case, tight_setup, os.path.join(d, "opensim_tight"))
    _, q_tight, _ = motion_matrix(problem, os.path.join(d, "opensim_tight", "opensim_ik.mot"))
    f_tight, _ = evaluate(problem, times, q_tight)
    gap = f_os / f_tight - 1
    dq = {problem.coord_names[k]: float(np.abs(q_tight[:, k] - q_os[:, k]).max()
                                        * ov.coordinate_unit(c)[0])
          for k, c in enumerate(problem.coords)}
    worst = max(dq, key=dq.get)
    print(f"OpenSim at accuracy {TIGHT_ACCURACY} vs its default run: F(default)/F(tight) - 1 "
          f"median {np.median(gap):.2e}, max {gap.max():.2e}; largest coordinate change "
          f"{dq[worst]:.4f} ({worst})")
    res.update(tight_gap_median=float(np.median(gap)), tight_gap_max=float(gap.max()),
               tight_max_coordinate_change=dq, objective_opensim_tight=f_tight.tolist())
    stationarity(problem, times, q_tight, res)

    stored_differences(problem, spec, times, q_os, f_os, res)

    mus_mot = None
    if args.self_test:
        mus_mot = os_mot
        print("self-test: OpenSim's own .mot stands in for musculo's")
    elif case in args.musculo_mot:
        mus_mot = args.musculo_mot[case]
    elif not args.opensim_only:
        mus_mot = os.path.join(d, "musculo", "musculo_ik.mot")
        ok, secs, out = ov.run_musculo(["ik", "--setup", setup, "-o", mus_mot],
                                       os.path.join(d, "musculo", "musculo_ik.log"))
        if not ok:
            print(out[-3000:])
            res["failures"].append("musculo ik failed")
            mus_mot = None
        else:
            res["musculo_seconds"] = secs
            print(f"musculo ik: {n} frames in {secs:.3f} s ({1000 * secs / n:.3f} ms/frame, "
                  f"whole process); OpenSim/musculo time ratio {seconds / secs:.1f}")
    if mus_mot:
        compare_solutions(problem, times, q_os, f_os, q_tight, mus_mot, res, args.self_test)
    report[case] = res
    for fmsg in res["failures"]:
        print(f"FAIL {case}: {fmsg}")
    return not res["failures"]


def stationarity(problem, times, q, res):
    """Checks the relative weight of the marker and coordinate terms of F against OpenSim.

    At OpenSim's tightly converged solution dF/dq_j = 0, so for a coordinate with a task the
    marker term's derivative must cancel the task's w_j (q_j - r_j): the ratio of the two is 1
    with F as written above (for sum_i w_i |e_i|^2 + sum_j w_j (q_j - r_j)^2 it would be
    sum(w_i) = 92.1 on gait2392). Frames where |q_j - r_j| < 1e-8 rad (the .mot's precision) are skipped.
    """
    ratios = []
    for i, t in enumerate(times):
        obs = problem.observed(t)
        for k, w, r in problem.coord_targets(t):
            if abs(q[i][k] - r) < 1e-8:
                continue
            terms = []
            for sign in (1, -1):
                qq = q[i].copy()
                qq[k] += sign * FD_STEP
                problem.objective(qq, t, obs)
                terms.append(problem.last_marker_term)
            g_markers = (terms[0] - terms[1]) / (2 * FD_STEP)
            ratios.append(-g_markers / (w * (q[i][k] - r)))
    if not ratios:
        print("stationarity check: no coordinate task away from its target (nothing to check)")
        return
    ratios = np.array(ratios)
    print(f"stationarity check at OpenSim's accuracy-{TIGHT_ACCURACY} solution: marker-term "
          f"slope / coordinate-task slope, {len(ratios)} (frame, task) pairs: median "
          f"{np.median(ratios):.4f}, range {ratios.min():.4f} to {ratios.max():.4f} (1 expected)")
    res["stationarity"] = dict(pairs=len(ratios), median=float(np.median(ratios)),
                               min=float(ratios.min()), max=float(ratios.max()))
    if np.any(np.abs(ratios - 1) > 0.05):
        res["failures"].append("the objective's marker/coordinate weighting disagrees with "
                               "OpenSim's solution (stationarity check)")


def compare_solutions(problem, times, q_os, f_os, q_tight, mus_mot, res, self_test=False):
    mt, q_mu, missing = motion_matrix(problem, mus_mot)
    fails = res["failures"]
    if missing:
        fails.append(f"musculo's .mot lacks coordinates {missing}")
    if len(mt) != len(times) or np.max(np.abs(mt - times)) > 1e-6:
        fails.append(f"musculo's frames differ: {len(mt)} rows, OpenSim {len(times)}")
        return
    for name in problem.locked:
        k = problem.coord_names.index(name)
        dev = np.max(np.abs(q_mu[:, k] - problem.defaults[k]))
        if dev > 1e-9:
            fails.append(f"locked coordinate {name} moved by {dev:.3g}")
    f_mu, tse_mu = evaluate(problem, times, q_mu)
    ratio = f_mu / f_os
    worst = int(np.argmax(ratio))
    bad = np.nonzero(f_mu > f_os * OBJECTIVE_RATIO + OBJECTIVE_ABS)[0]
    print(f"objective F(musculo)/F(OpenSim): median {np.median(ratio):.6f}, min {ratio.min():.6f}, "
          f"max {ratio.max():.6f} (frame {worst}, t={times[worst]:.4f}); "
          f"frames over {OBJECTIVE_RATIO}x+{OBJECTIVE_ABS:g}: {len(bad)}/{len(times)}")
    res.update(objective_musculo=f_mu.tolist(), ratio_median=float(np.median(ratio)),
               ratio_max=float(ratio.max()), ratio_min=float(ratio.min()), frames_over=len(bad))
    if len(bad):
        fails.append(f"objective over OpenSim's at {len(bad)} frames (largest ratio "
                     f"{ratio[worst]:.6f} at frame {worst})")

    # musculo's own error file, if written, against OpenSim's evaluation of its solution.
    err_path = os.path.splitext(mus_mot)[0] + "_ik_marker_errors.sto"
    if not os.path.exists(err_path):
        if not self_test:
            fails.append(f"no {os.path.basename(err_path)} beside musculo's .mot")
    else:
        et, ecols = ov.read_sto_columns(err_path)
        for col in ("total_squared_error", "marker_error_RMS", "marker_error_max"):
            if col not in ecols:
                fails.append(f"{os.path.basename(err_path)} lacks column {col}")
        if "total_squared_error" in ecols and len(ecols["total_squared_error"]) == len(tse_mu):
            rel = np.abs(ecols["total_squared_error"] - tse_mu) / np.maximum(tse_mu, 1e-300)
            print(f"musculo's total_squared_error vs OpenSim's evaluation of musculo's .mot: "
                  f"max rel. diff {rel.max():.2e}")
            res["musculo_error_file_rel_diff"] = float(rel.max())
            if rel.max() > 1e-4:
                fails.append(f"musculo's marker-error file disagrees with OpenSim ({rel.max():.2e})")

    # Coordinates: where are they well determined?
    rows = []
    allowed = np.zeros_like(q_os)
    for i, t in enumerate(times):
        h = problem.gauss_newton_hessian(q_os[i], t)
        try:
            hinv = np.linalg.inv(h)
            diag = np.diag(hinv)
        except np.linalg.LinAlgError:
            diag = np.full(len(h), np.inf)
        # Largest change of q_k (others re-optimised) that keeps F within 1 + WELL_DETERMINED_REL.
        allowed[i] = np.sqrt(2 * WELL_DETERMINED_REL * f_os[i] * np.maximum(diag, 0))
    res["coordinates"] = {}
    for k, c in enumerate(problem.coords):
        scale, unit, tol = ov.coordinate_unit(c)
        diff = np.abs(q_mu[:, k] - q_os[:, k])
        diff_tight = np.abs(q_mu[:, k] - q_tight[:, k])
        well = allowed[:, k] < tol
        wd = diff[well].max() if well.any() else float("nan")
        status = "ok"
        name = problem.coord_names[k]
        if name in problem.locked:
            status = "locked"
        elif well.any() and wd > tol:
            status = "FAIL"
            fails.append(f"{name}: {wd * scale:.3f} {unit} from OpenSim where well determined")
        rows.append([name, unit, f"{diff.max() * scale:.4f}", f"{np.median(diff) * scale:.4f}",
                     "n/a" if math.isnan(wd) else f"{wd * scale:.4f}",
                     f"{diff_tight.max() * scale:.4f}",
                     f"{well.sum()}/{len(well)}", f"{np.median(allowed[:, k]) * scale:.3g}", status])
        res["coordinates"][name] = dict(unit=unit, max=float(diff.max() * scale),
                                        max_well=None if math.isnan(wd) else float(wd * scale),
                                        max_vs_tight=float(diff_tight.max() * scale),
                                        well_frames=int(well.sum()),
                                        median_allowed=float(np.median(allowed[:, k]) * scale))
    print("per coordinate |musculo - OpenSim| (well determined: a move of 0.5 deg / 2 mm, others "
          "re-optimised, raises F by more than 0.01 %; 0.01%-spread: the move that does):")
    ov.print_table(["coordinate", "unit", "max", "median", "max (well det.)",
                    f"max vs acc. {TIGHT_ACCURACY}", "well-det. frames", "median 0.01%-spread",
                    "status"], rows)


def stored_differences(problem, spec, times, q_os, f_os, res):
    """How the .mot files stored in the reference folders differ from OpenSim 4.6's run."""
    res["stored"] = {}
    for path in spec["stored"]:
        if not os.path.exists(path):
            continue
        st, cols = ov.read_motion(path, problem.model)
        # The marker file's times are rounded to 1 ms (0.517 for 31/60 s): match within 4 ms.
        idx = [int(np.argmin(np.abs(st - t))) for t in times]
        match = [i for i, (j, t) in enumerate(zip(idx, times)) if abs(st[j] - t) < 0.004]
        if not match:
            print(f"stored {os.path.relpath(path, ov.MODELS)}: no frame at OpenSim's times")
            continue
        q_st = np.tile(problem.defaults, (len(match), 1))
        for k, n in enumerate(problem.coord_names):
            if n in cols:
                q_st[:, k] = cols[n][[idx[i] for i in match]]
        f_st, fm_st, rms_st, fm_os, rms_os = [], [], [], [], []
        nm = len(problem.markers)
        for a, i in enumerate(match):
            f, tse, _, _ = problem.objective(q_st[a], times[i])
            f_st.append(f)
            fm_st.append(problem.last_marker_term)
            rms_st.append(math.sqrt(tse / nm))
            _, tse, _, _ = problem.objective(q_os[i], times[i])
            fm_os.append(problem.last_marker_term)
            rms_os.append(math.sqrt(tse / nm))
        f_st, fm_st, fm_os = np.array(f_st), np.array(fm_st), np.array(fm_os)
        rows = []
        out = {}
        for k, c in enumerate(problem.coords):
            scale, unit, _ = ov.coordinate_unit(c)
            diff = np.abs(q_st[:, k] - q_os[match, k]) * scale
            a = int(np.argmax(diff))
            rows.append([problem.coord_names[k], unit, f"{diff.max():.3f}", f"{np.median(diff):.3f}",
                         f"{times[match[a]]:.3f}"])
            out[problem.coord_names[k]] = float(diff.max())
        ratio = f_st / f_os[match]
        mratio = fm_st / fm_os
        print(f"\nstored {os.path.relpath(path, ov.MODELS)} vs OpenSim 4.6's run "
              f"({len(match)} common frames): objective F(stored)/F(4.6) median "
              f"{np.median(ratio):.4g}, max {ratio.max():.4g}; marker term alone: median "
              f"{np.median(mratio):.4f}, min {mratio.min():.4f}, max {mratio.max():.4f}; marker "
              f"RMS (OpenSim's definition) median {1000 * np.median(rms_st):.2f} mm against "
              f"{1000 * np.median(rms_os):.2f} mm")
        ov.print_table(["coordinate", "unit", "max |diff|", "median", "at t"], rows)
        res["stored"][os.path.relpath(path, ov.MODELS)] = dict(
            max_diff=out, frames=len(match), ratio_median=float(np.median(ratio)),
            ratio_max=float(ratio.max()), marker_ratio_median=float(np.median(mratio)),
            marker_ratio_min=float(mratio.min()), marker_ratio_max=float(mratio.max()),
            rms_median_mm=1000 * float(np.median(rms_st)),
            rms_median_opensim_mm=1000 * float(np.median(rms_os)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", action="append", choices=sorted(CASES))
    ap.add_argument("--musculo-mot", action="append", default=[], metavar="CASE=FILE")
    ap.add_argument("--self-test", action="store_true")
    ap.add_argument("--opensim-only", action="store_true")
    ap.add_argument("--full-trial", action="store_true",
                    help="every frame of a case whose spec shortens the setup's time range")
    args = ap.parse_args()
    args.musculo_mot = dict(s.split("=", 1) for s in args.musculo_mot)
    ov.quiet_opensim()
    report = {}
    ok = True
    for case in args.case or sorted(CASES):
        ok &= compare_case(case, CASES[case], args, report)
    with open(os.path.join(ov.WORK, "ik_report.json"), "w", encoding="utf-8") as f:
        json.dump(report, f, indent=1)
    print(f"\nIK side by side: {'PASS' if ok else 'FAIL'} (details in "
          f"{os.path.relpath(os.path.join(ov.WORK, 'ik_report.json'), ov.REPO)})")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
