# Sourced by the tables' pool.sh records (here, ../grid_mended_tables/ and ../grid_size_tables/): add FOLDER MODEL
# appends to the array A an --agent argument of veragmil-pool-results for every agent of results/FOLDER/results.json
# named MODEL or "MODEL seed N", under its own name. Needs R (the results folder) and A (an array) set by the caller.
add() {
  local file="$R/$1/results.json" agent
  while IFS= read -r agent; do
    A+=(--agent "$agent=$file:$agent")
  done < <(python - "$file" "$2" <<'PY'
import json, re, sys
path, model = sys.argv[1:]
for agent in json.load(open(path))["config"]["agents"]:
    if re.fullmatch(re.escape(model) + r"( seed \d+)?", agent):
        print(agent)
PY
  )
}
