#!/usr/bin/env bash
# Make, or continue, the standard detection results (docs/results/*-standard): render the data set
# (resumable; the project alone fixes its fingerprint, so any sitting renders the same set), then
# train and test what the result folders lack, in WORKERS processes of one thread each that share
# the runs (job claims), niced so an interactive session keeps a core's worth of priority.
#   bash packaging/standard-results.sh [DATA_DIR] [CHECKPOINT_DIR] [WORKERS]
# Stop it at any time (kill the process group): finished runs are in docs/results; commit them.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:-data/city320}; ckpt=${2:-ckpt}; workers=${3:-2}
W=.venv/bin/workbench; R=docs/results; P=city_detection_quick
common=(--data "$data" --profile standard --checkpoints "$ckpt")
nice -n 5 "$W" dataset "$P" --frames 612 --out "$data" --workers "$workers"
settled_nets() {     # the nets whose budget B the budget study settled (B → 2B gains < 0.01 on 2 seeds)
  .venv/bin/python - "$R/budget-standard/results.json" <<'PY'
import json, sys
from workbench.experiments.budget import settled_nets
verdicts = json.load(open(sys.argv[1]))["budget_enough"]
for net, v in verdicts.items():
    print(f"{net}: {v.get('text', 'no verdict')}", file=sys.stderr)
print(" ".join(settled_nets(verdicts)))
PY
}
worker() {
  # resnet18 trains at batch 16 as the batch-16 ladder did (plan.STANDARD_BATCH): its runs there are lent
  nice -n 5 "$W" experiment budget "$P" "${common[@]}" --out "$R/budget-standard" \
    --reuse "$R/schedule-study/budget-batch16"
  # A net's ISP and exposure runs wait for its budget (at a budget that must still grow they would
  # be retrained; 'grow': set plan.STANDARD_EPOCHS to 2B, commit, run this script again); a net
  # whose budget is settled starts them while another net's study still trains.
  nets=$(settled_nets)
  [ -n "$nets" ] || { echo "ISP and exposure runs wait until a net's budget is settled"; return 0; }
  nice -n 5 "$W" experiment isp "$P" "${common[@]}" --nets $nets --out "$R/isp-standard" --reuse "$R/budget-standard"
  nice -n 5 "$W" experiment exposure "$P" "${common[@]}" --nets $nets --out "$R/exposure-standard" \
    --reuse "$R/budget-standard" "$R/isp-standard"
}
mkdir -p "$ckpt"
for k in $(seq "$workers"); do
  worker > "$ckpt/worker-$k.log" 2>&1 &
  sleep 5                     # the first creates the result folders; the next find them
done
wait
if .venv/bin/python -c 'import json, sys; from workbench.experiments.budget import settled_nets
v = json.load(open(sys.argv[1]))["budget_enough"]; sys.exit(len(settled_nets(v)) != len(v))' "$R/budget-standard/results.json"; then
  "$W" experiment claims --isp "$R/isp-standard" --exposure "$R/exposure-standard" --out "$R/claims-standard.md"
fi
