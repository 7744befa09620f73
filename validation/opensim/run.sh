#!/usr/bin/env bash
# Runs the OpenSim 4.6 side-by-side checks (validation/opensim/README.md): builds musculo
# (cargo build --release, examples/opensim_dynamics.rs, opensim_muscles.rs, dynamics_timing.rs),
# then the path-length, dynamics, muscle (lengthening speeds, forces at equilibrium), IK,
# Scale and ID/SO tool comparisons and the speed tables (augment_speed, dynamics_speed), each
# running OpenSim itself on the reference setups and musculo on the same setup copies under
# target/opensim-validation/.
#
# Usage:   eval "$(scripts/setup-opensim.sh)" && validation/opensim/run.sh [--opensim-only | --self-test]
#   --opensim-only   run and evaluate OpenSim's side only (no musculo)
#   --self-test      feed OpenSim's own outputs as musculo's (checks the comparison code)
# Without MUSCULO_OPENSIM_PYTHON it runs scripts/setup-opensim.sh itself. Exit status 1 when a
# tolerance fails; every check runs either way.
set -euo pipefail
cd "$(dirname "$0")/../.."

if [ -z "${MUSCULO_OPENSIM_PYTHON:-}" ]; then
    eval "$(scripts/setup-opensim.sh)"
fi
mode=()
case "${1:-}" in
    "") ;;
    --opensim-only|--self-test) mode=("$1") ;;
    *) echo "usage: $0 [--opensim-only | --self-test]" >&2; exit 2 ;;
esac

if [ ${#mode[@]} -eq 0 ]; then
    cargo build --release
    cargo build --release --example opensim_dynamics --example opensim_muscles --example dynamics_timing
fi

status=0
for check in paths_compare arm_paths_compare dynamics_compare muscles_compare scale_compare ik_compare tools_compare augment_speed dynamics_speed; do
    echo "== OpenSim side by side: $check ${mode[*]:-}"
    "$MUSCULO_OPENSIM_PYTHON" "validation/opensim/$check.py" "${mode[@]}" || status=1
done
if [ $status -ne 0 ]; then
    echo "== OpenSim side by side: FAILED (see above)"
else
    echo "== OpenSim side by side: passed"
fi
exit $status
