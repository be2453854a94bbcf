#!/usr/bin/env bash
# Runs a setup step with its output appended to a log that is shown only when the step fails:
#   bash scripts/quietly.sh LOG COMMAND [ARGUMENT...]
set -uo pipefail
log=$1
shift
mkdir -p "$(dirname "$log")"
"$@" >>"$log" 2>&1 && exit 0
status=$?
echo "failed: $* (exit $status); the end of its output, from $log:" >&2
tail -n 60 "$log" >&2
exit "$status"
