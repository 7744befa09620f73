"""The Inverse Dynamics, Static Optimization and Muscle Analysis tools side by side: OpenSim 4.6
against `musculo id`, `musculo so` and `musculo muscles` on the same setup copies. Both results
and run times are compared.

Cases. The setups are copied to target/opensim-validation/tools_compare/<case>/ with every path
made absolute. The models that the setups name beside themselves do not exist; their
OutputReference/ copies are used instead.
- gait2392 ID: Pipelines/Gait2392_Simbody/subject01_Setup_InverseDynamics.xml as written
  (0.4-1.6 s, 6 Hz low-pass, muscles excluded). Inputs: the model
  OutputReference/subject01_simbody.osim, the setup's own subject01_walk1_ik.mot (it starts at
  0.5 s, so the first rows come from the filter's padding, as in OpenSim), and
  subject01_walk1_grf.xml, whose copy names subject01_walk1_grf.mot by absolute path.
- gait2392 SO: Pipelines/Gait2392_Simbody/setup_static_optimization.xml. This setup and
  subject01_Setup_Analyze.xml are the pipeline's Analyze setups, and this is the one with a
  StaticOptimization analysis. It is run on the ID case's inputs: the same model, motion and
  loads, and the pipeline's gait2392_SO_Residual_Actuators.xml. The setup's own inputs are the
  RRA-adjusted model, RRA kinematics, foot_floor_loads.xml and the weak residuals. The setup's
  0.5-2.0 s, exponent 2 and muscle physiology are kept. Changed: step_interval 1 instead of 10,
  so that every frame is solved, and the 6 Hz low-pass of the ID setup, as the motion is raw IK.
  This gives 91 frames.
- gait2392 MuscleAnalysis: an AnalyzeTool setup written by this script (setup_muscle_analysis.xml)
  with one MuscleAnalysis. It covers all muscles and all coordinates, with compute_moments on,
  because OpenSim 4.6 computes moment arms only then. It runs on the same model and motion, cut
  to 0.5-1.0 s (31 frames, subject01_walk1_ik_0.5-1.0.mot, no filtering), with output precision
  16. musculo runs `musculo muscles MODEL --coords <that .mot>`.
- gait10dof ID: Pipelines/Gait10dof18musc/ID/walk_Setup_ID.xml as written (0-2.5 s, 6 Hz,
  151 rows). Inputs: OutputReference/subject01.osim, OutputReference/IK/subject01_walk_IK.mot,
  ExperimentalData/subject01_walk_grf.xml.
- gait10dof SO: the pipeline has no SO setup. gait2392's setup_static_optimization.xml is used
  with gait10dof's model, motion and loads, its gait10dof_Reserve_Actuators.xml, 0-2.5 s,
  step_interval 1 and the 6 Hz low-pass (151 frames). Its 18 muscles are
  Millard2012EquilibriumMuscle. It is also run on a copy of the model with every
  pennation_angle_at_optimal set to 0 ("gait10dof-nopenn", see the OpenSim defect below).

Results compared (exit status 1 when a tolerance fails):
- ID generalized forces, per column per frame: |tau_musculo - tau_OpenSim| <= 1e-6 + 1e-6 |tau|
  (N m or N). OpenSim writes 8 decimals, so rounding alone is 5e-9, and musculo reproduces
  OpenSim's padding, filtering and splining. Same rows, same times (1e-7 s), same columns.
- SO, per actuator per frame:
  * the force per unit control F/x (the force at full activation, set by the state alone:
    F_max f_L f_V cos(alpha) for a muscle, the optimal force for a reserve) to 1e-6 relative, on
    frames where both |x| > 1e-9. External-load columns of the force file:
    1e-6 + 1e-6 relative. Rows, times and columns must be the same.
  * objective J = sum_k |x_k|^p over every actuator (p from the setup). Per frame
    J_musculo <= J_OpenSim (1 + 1e-6).
  * activations: OpenSim's optimizer stops at its optimizer_convergence_criterion (default
    1e-4). On gait2392 its J is then 7e-5 to 9e-4 above its own optimum, and its activations
    are up to 0.007 from it. So the activations are judged against OpenSim rerun on the same
    setup with optimizer_convergence_criterion 1e-8 and optimizer_max_iterations 1000:
    |x_musculo - x_OpenSim,1e-8| <= 1e-3, and J_musculo <= J_OpenSim,1e-8 (1 + 1e-6).
    Differences to OpenSim's default run are printed for information.
    gait10dof-nopenn gets no rerun: at 1e-8 OpenSim takes ~280 s on it and still stops short
    at some frames, so only its objective is checked there.
  * OpenSim defect, gait10dof SO: Millard2012EquilibriumMuscle::calcActiveFiberForceAlongTendon
    (OpenSim 4.6, Millard2012EquilibriumMuscle.cpp line 1761) calls
    getPennationModel().calcPennationAngle(lceN) with the *normalised* fiber length. The
    pennation angle comes out as asin(h / (l/l_opt)) instead of asin(h / l), with
    h = l_opt sin(alpha_opt), so StaticOptimization's force at full activation is F_max f_L f_V
    cos(phi_wrong): up to 17 % too large for the pennated muscles. The evidence is computed
    here. The rigid-tendon fiber lengths l = sqrt(h^2 + (l_MT - l_s)^2) come from OpenSim's own
    MuscleAnalysis on the same setup, and musculo's F/x times cos(phi_wrong) / cos(phi) must
    reproduce OpenSim's F/x to 1e-6. OpenSim solves a different problem there, so activations
    and objective are not compared on the original model. On the zero-pennation copy,
    where the defect has no effect, F/x and the objective are checked as above.
- MuscleAnalysis: musculotendon lengths and moment arms, per muscle, coordinate and frame, to
  1e-9 m. musculo writes moment-arm files only for coordinates that some muscle spans; OpenSim
  writes every coordinate, and its other columns must be 0 there.

Timing (full mode only): each tool runs 3 times per side and the median is taken. OpenSim runs
in this process with fd 1 silenced: constructing the tool from its setup and tool.run(), model
loading included. musculo is timed as subprocess wall time: process start, model loading,
reading, solving and writing. Printed per tool: frames, OpenSim s, musculo s, ms per frame
each, and the ratio OpenSim/musculo. Also written to
target/opensim-validation/tools_compare/timing.json.
OpenSim's MuscleAnalysis also computes fiber and tendon quantities and moments (it cannot give
moment arms without them). `musculo muscles` writes lengths, moment arms and maximum isometric
moments.

Usage: tools_compare.py [--self-test | --opensim-only]
  --self-test      OpenSim's own outputs stand in for musculo's (the 1e-8 rerun for gait2392 SO):
                   every checked difference comes out 0 (the information rows against OpenSim's
                   default SO run show OpenSim's own gap); the pennation-defect check is skipped
  --opensim-only   run and evaluate OpenSim only (each tool once)
"""

import argparse
import json
import math
import os
import re
import statistics
import sys

import numpy as np

import osimval as ov
from augment_speed import silenced
from osimval import osim

P = os.path.join(ov.MODELS, "Pipelines")
G2392 = os.path.join(P, "Gait2392_Simbody")
G10 = os.path.join(P, "Gait10dof18musc")

ID_ABS, ID_REL = 1e-6, 1e-6
UNIT_FORCE_REL = 1e-6
OBJECTIVE_REL = 1e-6
ACTIVATION_ABS = 1e-3
PATH_ABS = 1e-9
TIGHT_CRITERION, TIGHT_MAX_ITERATIONS = "1e-8", "1000"
REPEATS = 3
MA_RANGE = (0.5, 1.0)

CASES = {
    "gait2392": dict(
        model=os.path.join(G2392, "OutputReference", "subject01_simbody.osim"),
        motion=os.path.join(G2392, "subject01_walk1_ik.mot"),
        grf_xml=os.path.join(G2392, "subject01_walk1_grf.xml"),
        grf_mot=os.path.join(G2392, "subject01_walk1_grf.mot"),
        reserves=os.path.join(G2392, "gait2392_SO_Residual_Actuators.xml"),
        id_setup=os.path.join(G2392, "subject01_Setup_InverseDynamics.xml"),
        id_output="InverseDynamicsOutput.sto",
        so_edits={"step_interval": "1", "lowpass_cutoff_frequency_for_coordinates": "6"},
        so_tight=True, muscle_analysis=True, nopenn=False),
    "gait10dof": dict(
        model=os.path.join(G10, "OutputReference", "subject01.osim"),
        motion=os.path.join(G10, "OutputReference", "IK", "subject01_walk_IK.mot"),
        grf_xml=os.path.join(G10, "ExperimentalData", "subject01_walk_grf.xml"),
        grf_mot=os.path.join(G10, "ExperimentalData", "subject01_walk_grf.mot"),
        reserves=os.path.join(G10, "gait10dof_Reserve_Actuators.xml"),
        id_setup=os.path.join(G10, "ID", "walk_Setup_ID.xml"),
        id_output="subject01_walk_ID.sto",
        so_edits={"step_interval": "1", "lowpass_cutoff_frequency_for_coordinates": "6",
                  "initial_time": "0", "final_time": "2.5",
                  "StaticOptimization/start_time": "0", "StaticOptimization/end_time": "2.5"},
        so_tight=False, muscle_analysis=False, nopenn=True),
}
SO_SETUP = os.path.join(G2392, "setup_static_optimization.xml")
SO_PREFIX = "subject01_StaticOptimization"  # the setup's AnalyzeTool name + analysis name


class Report:
    def __init__(self):
        self.failures = []
        self.results = {}

    def check(self, ok, message):
        if not ok:
            self.failures.append(message)
            print(f"FAIL {message}")
        return ok


# ---------------------------------------------------------------------------------------------
# Setups and runs


def with_so_convergence(src, dst, criterion, max_iterations, results_dir):
    """Copies an SO setup adding optimizer settings to its StaticOptimization analysis."""
    with open(src, encoding="utf-8") as f:
        text = f.read()
    text, n = re.subn(r"(<use_muscle_physiology>[^<]*</use_muscle_physiology>)",
                      rf"\1<optimizer_convergence_criterion>{criterion}"
                      rf"</optimizer_convergence_criterion><optimizer_max_iterations>"
                      rf"{max_iterations}</optimizer_max_iterations>", text)
    if n != 1 or "<optimizer_convergence_criterion>" in open(src, encoding="utf-8").read():
        sys.exit(f"{src}: cannot add the optimizer settings")
    with open(dst, "w", encoding="utf-8") as f:
        f.write(text)
    return ov.edit_setup(dst, dst, {"results_directory": results_dir})


def zero_pennation_model(src, dst):
    with open(src, encoding="utf-8") as f:
        text = f.read()
    text, n = re.subn(r"<pennation_angle_at_optimal>[^<]*</pennation_angle_at_optimal>",
                      "<pennation_angle_at_optimal>0</pennation_angle_at_optimal>", text)
    with open(dst, "w", encoding="utf-8") as f:
        f.write(text)
    return dst, n


def cut_motion(src, dst, t0, t1):
    """Writes the rows of a .mot with t0 <= time <= t1 (header kept, nRows updated)."""
    with open(src, encoding="utf-8") as f:
        lines = f.read().splitlines()
    end = next(i for i, ln in enumerate(lines) if ln.strip().lower() == "endheader")
    labels = end + 1
    while not lines[labels].strip():
        labels += 1
    rows = [ln for ln in lines[labels + 1:]
            if ln.strip() and t0 - 1e-6 <= float(ln.split()[0]) <= t1 + 1e-6]
    head = [re.sub(r"^nRows=\d+", f"nRows={len(rows)}", ln) for ln in lines[:labels + 1]]
    with open(dst, "w", encoding="utf-8") as f:
        f.write("\n".join(head + rows) + "\n")
    return dst, len(rows)


def muscle_analysis_setup(dst, name, model, motion, results_dir, t0, t1, lowpass, moments,
                          template=None):
    """An AnalyzeTool setup with one MuscleAnalysis (all muscles, all coordinates)."""
    if template:
        tool = osim.AnalyzeTool(template, False)
        tool.getAnalysisSet().clearAndDestroy()
    else:
        tool = osim.AnalyzeTool()
        tool.setModelFilename(model)
        tool.setCoordinatesFileName(motion)
        tool.setLowpassCutoffFrequency(lowpass)
        tool.setStartTime(t0)
        tool.setFinalTime(t1)
    tool.setName(name)
    tool.setResultsDir(results_dir)
    tool.setOutputPrecision(16)
    ma = osim.MuscleAnalysis()
    ma.setName("MuscleAnalysis")
    ma.setMuscles(osim.ArrayStr("all", 1))
    ma.setCoordinates(osim.ArrayStr("all", 1))
    ma.setComputeMoments(moments)
    tool.getAnalysisSet().cloneAndAppend(ma)
    tool.printToXML(dst)
    return dst


def run_opensim(what, make, repeats):
    """Runs an OpenSim tool `repeats` times (fd 1 silenced); returns the seconds of each run."""
    times = []
    for _ in range(repeats):
        ok, dt = silenced(lambda: make().run())
        if not ok:
            sys.exit(f"OpenSim's {what} failed")
        times.append(dt)
    return times


def run_musculo(what, args, log, repeats):
    times = []
    for _ in range(repeats):
        ok, dt, out = ov.run_musculo(args, log)
        if not ok:
            print(f"musculo {what} failed:\n{out[-3000:]}")
            return None
        times.append(dt)
    return times


# ---------------------------------------------------------------------------------------------
# Comparisons


def ts(t):
    """A time to 4 decimals, without a minus sign on -0.0000 (OpenSim's padded rows)."""
    return f"{round(float(t), 4) + 0.0:.4f}"


def read(path):
    t, cols = ov.read_sto_columns(path)
    return t, cols


def same_rows(rep, label, t_mu, t_os, cols_mu, cols_os):
    ok = rep.check(len(t_mu) == len(t_os), f"{label}: musculo {len(t_mu)} rows, OpenSim "
                   f"{len(t_os)}")
    if ok:
        dt = float(np.max(np.abs(t_mu - t_os))) if len(t_os) else 0.0
        ok = rep.check(dt <= 1e-7, f"{label}: row times differ by up to {dt:.2e} s")
    missing = sorted(set(cols_os) - set(cols_mu))
    extra = sorted(set(cols_mu) - set(cols_os))
    ok &= rep.check(not missing and not extra,
                    f"{label}: columns missing in musculo's {missing[:5]}, extra {extra[:5]}")
    return ok


def worst_table(title, entries, top=3):
    """entries: (score, column, frame time, |diff|, OpenSim value, allowed) with score =
    |diff| / allowed; prints the worst `top`."""
    entries = sorted(entries, key=lambda e: -e[0])[:top]
    rows = [[c, f"{ts(t)}", ov.fmt(d), ov.fmt(v), ov.fmt(a), f"{s:.3g}",
             "ok" if s <= 1 else "FAIL"] for s, c, t, d, v, a in entries]
    print(title)
    ov.print_table(["column", "t (s)", "|diff|", "OpenSim", "allowed", "|diff|/allowed",
                    "status"], rows)


def compare_id(rep, case, mu_path, os_path):
    t_mu, mu = read(mu_path)
    t_os, os_ = read(os_path)
    label = f"{case} ID"
    if not same_rows(rep, label, t_mu, t_os, mu, os_):
        return
    entries = []
    for c, v in os_.items():
        d = np.abs(mu[c] - v)
        allowed = ID_ABS + ID_REL * np.abs(v)
        i = int(np.argmax(d / allowed))
        entries.append((float(d[i] / allowed[i]), c, t_os[i], float(d[i]), float(v[i]),
                        float(allowed[i])))
    worst = max(entries, key=lambda e: e[0])
    print(f"{label}: {len(t_os)} rows x {len(os_)} generalized forces; largest |diff| "
          f"{max(e[3] for e in entries):.2e}; tolerance 1e-6 + 1e-6 |tau|")
    worst_table("worst columns:", entries)
    rep.results[label] = dict(rows=len(t_os), columns=len(os_),
                              max_abs_diff=max(e[3] for e in entries),
                              worst=dict(column=worst[1], time=worst[2], diff=worst[3],
                                         ratio_to_tolerance=worst[0]))
    rep.check(worst[0] <= 1, f"{label}: {worst[1]} at t={ts(worst[2])} differs by "
              f"{worst[3]:.3g} (allowed {worst[5]:.3g})")


def so_files(prefix):
    return prefix + "_activation.sto", prefix + "_force.sto"


def objective(cols, names, p):
    return np.sum(np.abs(np.array([cols[n] for n in names])) ** p, axis=0)


def millard_defect_factor(model_path, lengths_path):
    """{muscle: per-frame cos(phi_OpenSim) / cos(phi)} for the pennated Millard muscles, where
    phi_OpenSim = asin(h / (l / l_opt)) is OpenSim 4.6's angle in
    Millard2012EquilibriumMuscle::calcActiveFiberForceAlongTendon and phi = asin(h / l), l the
    rigid-tendon fiber length from OpenSim's musculotendon length at each frame."""
    model = osim.Model(model_path)
    _, lengths = read(lengths_path)
    out = {}
    muscles = model.getMuscles()
    for i in range(muscles.getSize()):
        m = muscles.get(i)
        alpha = m.getPennationAngleAtOptimalFiberLength()
        if m.getConcreteClassName() != "Millard2012EquilibriumMuscle" or alpha <= 1e-12:
            continue
        lopt = m.getOptimalFiberLength()
        h = lopt * math.sin(alpha)
        fiber = np.sqrt(h * h + (lengths[m.getName()] - m.getTendonSlackLength()) ** 2)
        sin_true, sin_os = h / fiber, h / (fiber / lopt)
        if np.any(sin_true >= 0.99) or np.any(sin_os >= 0.99):
            sys.exit(f"{m.getName()}: pennation near its maximum; the defect model does not "
                     "cover it")
        out[m.getName()] = np.sqrt(1 - sin_os ** 2) / np.sqrt(1 - sin_true ** 2)
    return out


def compare_so(rep, label, mu_prefix, os_prefix, exponent, tight_prefix=None, defect=None,
               check_objective=True, ours="musculo"):
    """Compares musculo's SO files (or those of `ours`) with OpenSim's (and OpenSim's tight
    rerun when given)."""
    a_mu_path, f_mu_path = so_files(mu_prefix)
    a_os_path, f_os_path = so_files(os_prefix)
    t_mu, a_mu = read(a_mu_path)
    t_os, a_os = read(a_os_path)
    _, f_mu = read(f_mu_path)
    _, f_os = read(f_os_path)
    ok = same_rows(rep, f"{label} activations", t_mu, t_os, a_mu, a_os)
    ok &= same_rows(rep, f"{label} forces", t_mu, t_os, f_mu, f_os)
    if not ok:
        return
    names = list(a_os)
    res = rep.results.setdefault(label, {})
    res.update(frames=len(t_os), actuators=len(names))
    rows = []

    # Force per unit control: fixed by the state (and the muscle model) alone.
    worst = (0.0, None, 0.0, 0.0, 0.0)
    for n in names:
        both = (np.abs(a_mu[n]) > 1e-9) & (np.abs(a_os[n]) > 1e-9)
        g_mu = np.where(both, f_mu[n] / np.where(both, a_mu[n], 1), 0)
        g_os = np.where(both, f_os[n] / np.where(both, a_os[n], 1), 0)
        if defect and n in defect:
            g_mu = g_mu * defect[n]
        rel = np.where(both, np.abs(g_mu - g_os) / np.maximum(np.abs(g_os), 1e-300), 0)
        i = int(np.argmax(rel))
        if rel[i] >= worst[0]:
            worst = (float(rel[i]), n, t_os[i], float(g_mu[i]), float(g_os[i]))
    what = (f"F/x, {ours} x OpenSim's pennation defect" if defect
            else "F/x (full-activation force)")
    rows.append([what, f"{worst[1]} @ {ts(worst[2])}", f"{worst[0]:.2e} rel.",
                 f"{UNIT_FORCE_REL:g} rel.", "ok" if worst[0] <= UNIT_FORCE_REL else "FAIL"])
    res["unit_force_max_rel"] = worst[0]
    rep.check(worst[0] <= UNIT_FORCE_REL, f"{label}: force per unit control of {worst[1]} at "
              f"t={ts(worst[2])}: {ours} {worst[3]:.10g}, OpenSim {worst[4]:.10g}")

    # External-load columns of the force file.
    extra = [c for c in f_os if c not in a_os]
    if extra:
        sc = [(float(np.max(np.abs(f_mu[c] - f_os[c]) / (ID_ABS + ID_REL * np.abs(f_os[c])))),
               c) for c in extra]
        s, c = max(sc)
        rows.append([f"external-load columns ({len(extra)})", c,
                     f"{np.max(np.abs(f_mu[c] - f_os[c])):.2e}", "1e-6 + 1e-6 rel.",
                     "ok" if s <= 1 else "FAIL"])
        rep.check(s <= 1, f"{label}: external-load column {c} differs")

    # Objective against OpenSim's run.
    j_mu, j_os = objective(a_mu, names, exponent), objective(a_os, names, exponent)
    ratio = j_mu / j_os
    i = int(np.argmax(ratio))
    res.update(objective_ratio_min=float(ratio.min()), objective_ratio_max=float(ratio.max()),
               objective_ratio_median=float(np.median(ratio)))
    if check_objective:
        rows.append([f"J_{ours} / J_OpenSim per frame",
                     f"max @ {ts(t_os[i])} (min {ratio.min():.9f})", f"{ratio[i]:.9f}",
                     f"<= 1 + {OBJECTIVE_REL:g}",
                     "ok" if ratio[i] <= 1 + OBJECTIVE_REL else "FAIL"])
        rep.check(ratio[i] <= 1 + OBJECTIVE_REL, f"{label}: objective {ratio[i]:.7f} x "
                  f"OpenSim's at t={ts(t_os[i])}")

    # Activations and forces against OpenSim's run (information).
    def act_diff(a, b):
        best = (0.0, None, 0.0)
        for n in names:
            d = np.abs(a[n] - b[n])
            k = int(np.argmax(d))
            if d[k] >= best[0]:
                best = (float(d[k]), n, t_os[k])
        return best

    def force_diff(fa, fb):
        best = (0.0, None, 0.0)
        for n in names:
            d = np.abs(fa[n] - fb[n])
            k = int(np.argmax(d))
            if d[k] >= best[0]:
                best = (float(d[k]), n, t_os[k])
        return best

    d_act = act_diff(a_mu, a_os)
    d_f = force_diff(f_mu, f_os)
    rows.append([f"|x_{ours} - x_OpenSim| (information)", f"{d_act[1]} @ {ts(d_act[2])}",
                 f"{d_act[0]:.2e}", "-", "info"])
    rows.append([f"|F_{ours} - F_OpenSim| (N, information)", f"{d_f[1]} @ {ts(d_f[2])}",
                 f"{d_f[0]:.3g}", "-", "info"])
    res.update(activation_max_diff_default=d_act[0], force_max_diff_default=d_f[0])

    if tight_prefix:
        a_t_path, f_t_path = so_files(tight_prefix)
        t_t, a_t = read(a_t_path)
        _, f_t = read(f_t_path)
        if same_rows(rep, f"{label} tight activations", t_t, t_os, a_t, a_os):
            j_t = objective(a_t, names, exponent)
            gap = j_os / j_t
            r_t = j_mu / j_t
            k = int(np.argmax(r_t))
            d_t = act_diff(a_mu, a_t)
            d_ft = force_diff(f_mu, f_t)
            d_os_t = act_diff(a_os, a_t)
            rows.append([f"J_OpenSim / J_OpenSim,{TIGHT_CRITERION} (information)",
                         f"min {gap.min():.7f}", f"max {gap.max():.7f}", "-", "info"])
            rows.append([f"|x_OpenSim - x_OpenSim,{TIGHT_CRITERION}| (information)",
                         f"{d_os_t[1]} @ {ts(d_os_t[2])}", f"{d_os_t[0]:.2e}", "-", "info"])
            rows.append([f"J_{ours} / J_OpenSim,{TIGHT_CRITERION} per frame",
                         f"max @ {ts(t_os[k])} (min {r_t.min():.9f})", f"{r_t[k]:.9f}",
                         f"<= 1 + {OBJECTIVE_REL:g}",
                         "ok" if r_t[k] <= 1 + OBJECTIVE_REL else "FAIL"])
            rows.append([f"|x_{ours} - x_OpenSim,{TIGHT_CRITERION}|",
                         f"{d_t[1]} @ {ts(d_t[2])}", f"{d_t[0]:.2e}", f"{ACTIVATION_ABS:g}",
                         "ok" if d_t[0] <= ACTIVATION_ABS else "FAIL"])
            rows.append([f"|F_{ours} - F_OpenSim,{TIGHT_CRITERION}| (N, information)",
                         f"{d_ft[1]} @ {ts(d_ft[2])}", f"{d_ft[0]:.3g}", "-", "info"])
            res.update(opensim_gap_min=float(gap.min()), opensim_gap_max=float(gap.max()),
                       opensim_vs_tight_activation=d_os_t[0],
                       objective_ratio_tight_max=float(r_t.max()),
                       objective_ratio_tight_min=float(r_t.min()),
                       activation_max_diff_tight=d_t[0], activation_worst_tight=d_t[1],
                       force_max_diff_tight=d_ft[0])
            rep.check(r_t[k] <= 1 + OBJECTIVE_REL, f"{label}: objective {r_t[k]:.7f} x "
                      f"OpenSim's at criterion {TIGHT_CRITERION}, t={ts(t_os[k])}")
            rep.check(d_t[0] <= ACTIVATION_ABS, f"{label}: {d_t[1]} activation at "
                      f"t={ts(d_t[2])} differs by {d_t[0]:.3g} from OpenSim at criterion "
                      f"{TIGHT_CRITERION}")
    print(f"{label}: {len(t_os)} frames x {len(names)} actuators, exponent {exponent:g}")
    ov.print_table(["check", "worst (actuator @ t s)", "value", "tolerance", "status"], rows)


def compare_muscle_analysis(rep, label, mu_prefix, os_dir, os_name):
    t_os, l_os = read(os.path.join(os_dir, f"{os_name}_MuscleAnalysis_Length.sto"))
    t_mu, l_mu = read(mu_prefix + "_Length.sto")
    if not same_rows(rep, f"{label} lengths", t_mu, t_os, l_mu, l_os):
        return
    worst_len = max((float(np.max(np.abs(l_mu[m] - l_os[m]))), m) for m in l_os)
    worst_arm = (0.0, None, None)
    coords = 0
    not_written = []
    for f in sorted(os.listdir(os_dir)):
        m = re.match(rf"{re.escape(os_name)}_MuscleAnalysis_MomentArm_(.+)\.sto$", f)
        if not m:
            continue
        coords += 1
        coord = m.group(1)
        t_a, r_os = read(os.path.join(os_dir, f))
        mu_path = f"{mu_prefix}_MomentArm_{coord}.sto"
        if os.path.exists(mu_path):
            t_b, r_mu = read(mu_path)
            if not same_rows(rep, f"{label} moment arms {coord}", t_b, t_a, r_mu, r_os):
                continue
        else:
            not_written.append(coord)
            r_mu = {k: np.zeros_like(v) for k, v in r_os.items()}
        for k, v in r_os.items():
            d = float(np.max(np.abs(r_mu[k] - v)))
            if d >= worst_arm[0]:
                worst_arm = (d, k, coord)
    print(f"{label}: {len(t_os)} frames, {len(l_os)} muscles, {coords} coordinates "
          f"(musculo writes no file for {len(not_written)} that no muscle spans: "
          f"{', '.join(not_written) or '-'}; OpenSim's must be 0 there)")
    ov.print_table(["quantity", "worst", "max |diff| (m)", "tolerance (m)", "status"], [
        ["musculotendon length", worst_len[1], ov.fmt(worst_len[0]), f"{PATH_ABS:g}",
         "ok" if worst_len[0] <= PATH_ABS else "FAIL"],
        ["moment arm", f"{worst_arm[1]} / {worst_arm[2]}", ov.fmt(worst_arm[0]),
         f"{PATH_ABS:g}", "ok" if worst_arm[0] <= PATH_ABS else "FAIL"]])
    rep.results[label] = dict(frames=len(t_os), muscles=len(l_os), coordinates=coords,
                              length_max_diff=worst_len[0], moment_arm_max_diff=worst_arm[0])
    rep.check(worst_len[0] <= PATH_ABS, f"{label}: length of {worst_len[1]} differs by "
              f"{worst_len[0]:.3g} m")
    rep.check(worst_arm[0] <= PATH_ABS, f"{label}: moment arm of {worst_arm[1]} about "
              f"{worst_arm[2]} differs by {worst_arm[0]:.3g} m")


# ---------------------------------------------------------------------------------------------


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--self-test", action="store_true")
    ap.add_argument("--opensim-only", action="store_true")
    args = ap.parse_args()
    full = not (args.self_test or args.opensim_only)
    repeats = REPEATS if full else 1
    for spec in CASES.values():
        for key in ("model", "motion", "grf_xml", "grf_mot", "reserves", "id_setup"):
            ov.require(spec[key], key)
    ov.require(SO_SETUP, "SO setup")
    if full:
        for cmd in ("id", "so", "muscles"):
            if not ov.musculo_has(cmd):
                sys.exit(f"{ov.MUSCULO} lacks `{cmd}` (cargo build --release)")
    ov.quiet_opensim()
    root = ov.fresh_dir(os.path.join(ov.WORK, "tools_compare"))
    rep = Report()
    timing = []

    def timed(tool, case, frames, os_times, mu_times):
        timing.append(dict(tool=tool, case=case, frames=frames, opensim_runs_s=os_times,
                           musculo_runs_s=mu_times))

    for case, spec in CASES.items():
        d = os.path.join(root, case)
        os.makedirs(os.path.join(d, "opensim"))
        os.makedirs(os.path.join(d, "musculo"))
        loads = ov.edit_setup(spec["grf_xml"], os.path.join(d, "grf.xml"),
                              {"datafile": spec["grf_mot"]})

        # ---- Inverse dynamics
        print(f"\n=== {case} ID: {os.path.relpath(spec['id_setup'], ov.MODELS)}")
        id_setup = ov.edit_setup(spec["id_setup"], os.path.join(d, "setup_id.xml"), {
            "model_file": spec["model"], "coordinates_file": spec["motion"],
            "external_loads_file": loads, "results_directory": os.path.join(d, "opensim")})
        os_id = os.path.join(d, "opensim", spec["id_output"])
        t_os = run_opensim(f"{case} InverseDynamicsTool",
                           lambda: osim.InverseDynamicsTool(id_setup), repeats)
        frames = osim.Storage(os_id).getSize()
        print(f"OpenSim InverseDynamicsTool: {frames} rows, {statistics.median(t_os):.3f} s")
        mu_id, t_mu = None, None
        if args.self_test:
            mu_id = os_id
        elif full:
            mu_id = os.path.join(d, "musculo", "id.sto")
            t_mu = run_musculo("id", ["id", "--setup", id_setup, "-o", mu_id],
                               os.path.join(d, "musculo", "id.log"), repeats)
            rep.check(t_mu is not None, f"{case}: musculo id failed")
            mu_id = mu_id if t_mu else None
        if mu_id:
            compare_id(rep, case, mu_id, os_id)
        timed("ID", case, frames, t_os, t_mu)

        # ---- Static optimization
        print(f"\n=== {case} SO: {os.path.relpath(SO_SETUP, ov.MODELS)}"
              + (" (the pipeline has none; gait2392's, with this case's inputs)"
                 if case != "gait2392" else ""))
        so_edits = {"model_file": spec["model"], "force_set_files": spec["reserves"],
                    "coordinates_file": spec["motion"], "external_loads_file": loads,
                    "results_directory": os.path.join(d, "opensim")}
        so_edits.update(spec["so_edits"])
        so_setup = ov.edit_setup(SO_SETUP, os.path.join(d, "setup_so.xml"), so_edits)
        tool0 = osim.AnalyzeTool(so_setup, False)
        so_an = osim.StaticOptimization.safeDownCast(tool0.getAnalysisSet().get(0))
        exponent = so_an.getActivationExponent()
        os_so = os.path.join(d, "opensim", SO_PREFIX)
        t_os = run_opensim(f"{case} AnalyzeTool (StaticOptimization)",
                           lambda: osim.AnalyzeTool(so_setup), repeats)
        frames = osim.Storage(so_files(os_so)[0]).getSize()
        print(f"OpenSim AnalyzeTool (StaticOptimization): {frames} frames, "
              f"{statistics.median(t_os):.3f} s")
        tight = None
        if spec["so_tight"]:
            tight_dir = os.path.join(d, f"opensim_criterion_{TIGHT_CRITERION}")
            os.makedirs(tight_dir)
            tight_setup = with_so_convergence(so_setup, os.path.join(d, "setup_so_tight.xml"),
                                              TIGHT_CRITERION, TIGHT_MAX_ITERATIONS, tight_dir)
            t_tight = run_opensim(f"{case} SO at criterion {TIGHT_CRITERION}",
                                  lambda: osim.AnalyzeTool(tight_setup), 1)
            tight = os.path.join(tight_dir, SO_PREFIX)
            print(f"OpenSim rerun at optimizer_convergence_criterion {TIGHT_CRITERION}: "
                  f"{t_tight[0]:.3f} s")
        mu_so, t_mu = None, None
        if args.self_test:
            mu_so = tight or os_so
        elif full:
            mu_so = os.path.join(d, "musculo", "so")
            t_mu = run_musculo("so", ["so", "--setup", so_setup, "-o", mu_so],
                               os.path.join(d, "musculo", "so.log"), repeats)
            rep.check(t_mu is not None, f"{case}: musculo so failed")
            mu_so = mu_so if t_mu else None
        timed("SO", case, frames, t_os, t_mu)
        defect = None
        if spec["nopenn"] and not args.self_test:
            # Rigid-tendon fiber lengths at SO's frames, from OpenSim, for the defect's evidence.
            len_dir = os.path.join(d, "opensim_lengths")
            len_setup = muscle_analysis_setup(os.path.join(d, "setup_lengths.xml"), "lengths",
                                              None, None, len_dir, 0, 0, 0, False,
                                              template=so_setup)
            run_opensim(f"{case} MuscleAnalysis (lengths)", lambda: osim.AnalyzeTool(len_setup), 1)
            defect = millard_defect_factor(
                spec["model"], os.path.join(len_dir, "lengths_MuscleAnalysis_Length.sto"))
            print(f"OpenSim defect (Millard2012EquilibriumMuscle pennation from the normalised "
                  f"fiber length) modelled for {len(defect)} pennated muscles: cos(phi_OpenSim)"
                  f"/cos(phi) from {min(v.min() for v in defect.values()):.4f} to "
                  f"{max(v.max() for v in defect.values()):.4f}")
        if args.self_test and spec["nopenn"]:
            print("self-test: the pennation-defect check is skipped (OpenSim's own F/x carries "
                  "the defect)")
        if mu_so:
            if spec["nopenn"] and not args.self_test:
                compare_so(rep, f"{case} SO", mu_so, os_so, exponent, defect=defect,
                           check_objective=False)
            elif not spec["nopenn"]:
                compare_so(rep, f"{case} SO", mu_so, os_so, exponent, tight_prefix=tight)
        elif args.opensim_only and tight:
            compare_so(rep, f"{case} SO (OpenSim's rerun against its default run)", tight,
                       os_so, exponent, ours=f"OpenSim,{TIGHT_CRITERION}")

        if spec["nopenn"]:
            label = f"{case}-nopenn SO"
            print(f"\n=== {label}: every pennation_angle_at_optimal set to 0")
            model_np, n = zero_pennation_model(spec["model"], os.path.join(d, "model_nopenn.osim"))
            print(f"{n} muscles' pennation set to 0 in {os.path.relpath(model_np, ov.REPO)}")
            np_dir = os.path.join(d, "opensim_nopenn")
            os.makedirs(np_dir)
            np_setup = ov.edit_setup(so_setup, os.path.join(d, "setup_so_nopenn.xml"),
                                     {"model_file": model_np, "results_directory": np_dir})
            t_np = run_opensim(f"{label}", lambda: osim.AnalyzeTool(np_setup), 1)
            print(f"OpenSim AnalyzeTool (StaticOptimization): {t_np[0]:.3f} s")
            os_np = os.path.join(np_dir, SO_PREFIX)
            mu_np = None
            if args.self_test:
                mu_np = os_np
            elif full:
                mu_np = os.path.join(d, "musculo", "so_nopenn")
                t_mu = run_musculo("so", ["so", "--setup", np_setup, "-o", mu_np],
                                   os.path.join(d, "musculo", "so_nopenn.log"), 1)
                rep.check(t_mu is not None, f"{label}: musculo so failed")
                mu_np = mu_np if t_mu else None
            if mu_np:
                compare_so(rep, label, mu_np, os_np, exponent)

        # ---- Muscle analysis
        if spec["muscle_analysis"]:
            print(f"\n=== {case} MuscleAnalysis: all muscles, all coordinates, "
                  f"{MA_RANGE[0]}-{MA_RANGE[1]} s")
            stem = os.path.splitext(os.path.basename(spec["motion"]))[0]
            motion, n_rows = cut_motion(
                spec["motion"], os.path.join(d, f"{stem}_{MA_RANGE[0]}-{MA_RANGE[1]}.mot"),
                *MA_RANGE)
            ma_dir = os.path.join(d, "opensim_muscle_analysis")
            ma_setup = muscle_analysis_setup(os.path.join(d, "setup_muscle_analysis.xml"), case,
                                             spec["model"], motion, ma_dir, MA_RANGE[0],
                                             MA_RANGE[1], -1, True)
            t_os = run_opensim(f"{case} AnalyzeTool (MuscleAnalysis)",
                               lambda: osim.AnalyzeTool(ma_setup), repeats)
            frames = osim.Storage(
                os.path.join(ma_dir, f"{case}_MuscleAnalysis_Length.sto")).getSize()
            print(f"OpenSim AnalyzeTool (MuscleAnalysis): {frames} frames ({n_rows} in the "
                  f".mot), {statistics.median(t_os):.3f} s")
            mu_ma, t_mu = None, None
            if args.self_test:
                mu_ma = os.path.join(ma_dir, f"{case}_MuscleAnalysis")
            elif full:
                mu_ma = os.path.join(d, "musculo", "muscles")
                t_mu = run_musculo("muscles", ["muscles", spec["model"], "--coords", motion,
                                               "-o", mu_ma],
                                   os.path.join(d, "musculo", "muscles.log"), repeats)
                rep.check(t_mu is not None, f"{case}: musculo muscles failed")
                mu_ma = mu_ma if t_mu else None
            if mu_ma:
                compare_muscle_analysis(rep, f"{case} MuscleAnalysis", mu_ma, ma_dir, case)
            timed("MuscleAnalysis", case, frames, t_os, t_mu)

    # ---- Timing
    print(f"\n=== Timing ({'median of ' + str(REPEATS) + ' runs' if full else 'one run'}; "
          "OpenSim in-process with fd 1 silenced, tool construction and model loading included; "
          "musculo as subprocess wall time, process start and model loading included)")
    rows = []
    for t in timing:
        t["opensim_s"] = statistics.median(t["opensim_runs_s"])
        t["opensim_ms_per_frame"] = 1000 * t["opensim_s"] / t["frames"]
        if t["musculo_runs_s"]:
            t["musculo_s"] = statistics.median(t["musculo_runs_s"])
            t["musculo_ms_per_frame"] = 1000 * t["musculo_s"] / t["frames"]
            t["ratio_opensim_over_musculo"] = t["opensim_s"] / t["musculo_s"]
        rows.append([f"{t['tool']} {t['case']}", str(t["frames"]), f"{t['opensim_s']:.3f}",
                     f"{t['musculo_s']:.3f}" if "musculo_s" in t else "-",
                     f"{t['opensim_ms_per_frame']:.2f}",
                     f"{t['musculo_ms_per_frame']:.3f}" if "musculo_s" in t else "-",
                     ov.fmt(t['ratio_opensim_over_musculo'], 3) if "musculo_s" in t else "-"])
    ov.print_table(["tool", "frames", "OpenSim s", "musculo s", "OpenSim ms/frame",
                    "musculo ms/frame", "OpenSim/musculo"], rows)
    if full:
        with open(os.path.join(root, "timing.json"), "w", encoding="utf-8") as f:
            json.dump(dict(repeats=REPEATS, statistic="median",
                           opensim="in-process, fd 1 silenced, tool construction from the setup "
                                   "and run(), model loading included",
                           musculo="subprocess wall time, process start and model loading "
                                   "included", tools=timing), f, indent=1)
    with open(os.path.join(root, "report.json"), "w", encoding="utf-8") as f:
        json.dump(dict(results=rep.results, failures=rep.failures), f, indent=1)
    ok = not rep.failures
    print(f"\nID/SO/MuscleAnalysis tools side by side: {'PASS' if ok else 'FAIL'} "
          f"({len(rep.failures)} failure(s); details in "
          f"{os.path.relpath(os.path.join(root, 'report.json'), ov.REPO)}"
          f"{', timing.json' if full else ''})")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
