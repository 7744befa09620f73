"""The augmentation chain side by side with OpenSim 4.6: the same trial (the gait2392 walk,
subject01_simbody.osim, 151 marker frames, its force plates) through OpenSim's tools — Inverse
Kinematics, Inverse Dynamics, and Static Optimization (Analyze tool, every frame, the
pipeline's residual actuators added) — and through `musculo augment --external-loads`, which
does IK, filtering, ID, SO over the same 92 muscles with reserves, excitations and the
per-joint layout and writes the tensors. Both are timed as whole runs (model loading included)
in this process's machine; the figure is the ratio of the wall times. OpenSim's SO setup uses
the pipeline's settings (exponent 2, muscle physiology, 6 Hz low-pass).

Usage: augment_speed.py   (run by validation/opensim/run.sh; needs target/release/musculo)
"""

import os
import sys
import time

import osimval as ov
from osimval import osim

G = os.path.join(ov.MODELS, "Pipelines", "Gait2392_Simbody")
MODEL = os.path.join(G, "OutputReference", "subject01_simbody.osim")
TRC = os.path.join(G, "subject01_walk1.trc")
GRF_XML = os.path.join(G, "subject01_walk1_grf.xml")
GRF_MOT = os.path.join(G, "subject01_walk1_grf.mot")
RESERVES = os.path.join(G, "gait2392_SO_Residual_Actuators.xml")


def silenced(run):
    """Runs `run()` with fd 1 silenced (OpenSim prints per frame); returns (result, seconds)."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    try:
        t0 = time.perf_counter()
        result = run()
        return result, time.perf_counter() - t0
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(devnull)
        os.close(saved)


def main():
    if any(a in ("--self-test", "--opensim-only") for a in sys.argv[1:]):
        print("augment_speed: a timing of both programs; nothing to check in this mode")
        return
    for p, what in [(MODEL, "model"), (TRC, "markers"), (GRF_XML, "external loads"),
                    (GRF_MOT, "ground reactions"), (RESERVES, "reserve actuators")]:
        ov.require(p, what)
    ov.quiet_opensim()
    d = ov.fresh_dir(os.path.join(ov.WORK, "augment_speed"))
    os.makedirs(os.path.join(d, "opensim"))
    ik_mot = os.path.join(d, "opensim", "ik.mot")
    loads = ov.edit_setup(GRF_XML, os.path.join(d, "grf.xml"), {"datafile": GRF_MOT})
    ik_setup = ov.edit_setup(os.path.join(G, "subject01_Setup_IK.xml"),
                             os.path.join(d, "setup_ik.xml"), {
                                 "model_file": MODEL, "marker_file": TRC,
                                 "results_directory": os.path.join(d, "opensim"),
                                 "output_motion_file": ik_mot, "time_range": "0 100"})
    id_setup = ov.edit_setup(os.path.join(G, "subject01_Setup_InverseDynamics.xml"),
                             os.path.join(d, "setup_id.xml"), {
                                 "model_file": MODEL, "coordinates_file": ik_mot,
                                 "external_loads_file": loads,
                                 "results_directory": os.path.join(d, "opensim"),
                                 "time_range": "0 100"})
    so_setup = ov.edit_setup(os.path.join(G, "setup_static_optimization.xml"),
                             os.path.join(d, "setup_so.xml"), {
                                 "model_file": MODEL, "force_set_files": RESERVES,
                                 "coordinates_file": ik_mot, "external_loads_file": loads,
                                 "results_directory": os.path.join(d, "opensim"),
                                 "initial_time": "0", "final_time": "100",
                                 "step_interval": "1",
                                 "lowpass_cutoff_frequency_for_coordinates": "6"})
    ok_ik, t_ik = silenced(lambda: osim.InverseKinematicsTool(ik_setup).run())
    ok_id, t_id = silenced(lambda: osim.InverseDynamicsTool(id_setup).run())
    ok_so, t_so = silenced(lambda: osim.AnalyzeTool(so_setup).run())
    if not (ok_ik and ok_id and ok_so):
        sys.exit(f"OpenSim failed: IK {ok_ik}, ID {ok_id}, SO {ok_so}")
    t_opensim = t_ik + t_id + t_so
    out = os.path.join(d, "musculo")
    ok, t_musculo, log = ov.run_musculo(
        ["augment", "--model", MODEL, "--input", TRC, "--no-scale", "--external-loads", GRF_XML,
         "--out", out, "--jobs", "1"], os.path.join(d, "musculo.log"))
    if not ok:
        sys.exit(f"musculo augment failed:\n{log}")
    frames = osim.Storage(ik_mot).getSize()
    so_rows = osim.Storage(os.path.join(
        d, "opensim", "subject01_StaticOptimization_activation.sto")).getSize()
    if frames != 151:
        sys.exit(f"OpenSim IK solved {frames} frames, expected the trial's 151")
    print(f"gait2392 walk, {frames} frames (OpenSim's SO writes {so_rows} rows: its filter pads "
          f"the record), one thread each:")
    print(f"  OpenSim 4.6: IK {t_ik:.2f} s + ID {t_id:.2f} s + SO {t_so:.2f} s = {t_opensim:.2f} s"
          f" ({frames / t_opensim:.1f} frames/s)")
    print(f"  musculo augment (IK, ID, SO, excitations, layout, .npz): {t_musculo:.2f} s"
          f" ({frames / t_musculo:.0f} frames/s)")
    print(f"  ratio musculo / OpenSim, whole runs: {t_musculo / t_opensim:.4f}"
          f" ({t_opensim / t_musculo:.0f}x faster); per solved row (OpenSim {frames} IK + "
          f"{so_rows} SO rows, musculo {frames}): "
          f"{(t_musculo / frames) / ((t_ik / frames) + (t_id + t_so) / so_rows):.4f}")


if __name__ == "__main__":
    main()
