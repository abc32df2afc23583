#!/usr/bin/env bash
# Accuracy regression gate: run every validation case at the smoke tier, then hold its metrics
# against the committed baseline (validations/baselines/smoke/, see the README there).
# Exit status: 0 when every case passes its checks and no metric regressed beyond its tolerance;
# 1 when a case fails or a metric regressed; 2 when the baseline is unusable.
# Usage: .ci/validate_smoke.sh [OUT]    OUT: report folder (default: a new temp folder)
#        JOBS=N .ci/validate_smoke.sh   worker processes (default 2)
#        BASELINE=PATH                  another baseline folder or results.json
set -euo pipefail

cd "$(dirname "$0")/.."
python="${PYTHON:-python}"
out="${1:-$(mktemp -d "${TMPDIR:-/tmp}/mpsbench-smoke.XXXXXX")}"
baseline="${BASELINE:-validations/baselines/smoke}"

status=0
# The baseline holds the reference backend's metrics (validate's default is numba when installed).
"$python" -m mpsbench validate all --tier smoke --solver reference --jobs "${JOBS:-2}" \
    --out "$out" || status=$?
if ((status == 2)); then
    exit 2  # usage error: nothing ran
fi
# Compare even when a check failed, so the log shows which numbers moved.
compared=0
"$python" -m mpsbench compare "$baseline" "$out" || compared=$?
echo "smoke report: $out/index.html; comparison: $out/compare.md"
if ((compared != 0)); then
    exit "$compared"
fi
exit "$status"
