#!/bin/bash
# lines: "cyl JSON" or "env JSON"
cd /work/main; export MUJOCO_GL=osmesa PYTHONPATH=/work/proto/pkg
while read -r kind cfg; do
  [ -z "$cfg" ] && continue
  if [ "$kind" = cyl ]; then script=/work/proto/cyl2.py; else script=/work/proto/envspeed.py; fi
  timeout 1800 .venv/bin/python $script "$cfg" 2>/tmp/mixed_err.txt | grep '^{' | sed "s/^{/{\"kind\": \"$kind\", /" >> "$1" || echo "{\"fail\": $cfg}" >> "$1"
done < "$2"
echo DONE >> "$1"
