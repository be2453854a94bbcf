# Sourced by the tables' pool.sh records (here, ../grid_mended_tables/ and ../grid_size_tables/), run from the
# repository root. Each record fills the arrays A (agents) and P (pairs) and calls pool_tables with its folder's name.
#   add FOLDER MODEL [SEED]
#                     appends to A an --agent argument of veragmil-pool-results for every agent of
#                     results/FOLDER/results.json named MODEL or "MODEL seed N", under its own name; with SEED, an
#                     agent named MODEL alone (a study of one training seed names no seed) is named "MODEL seed SEED",
#                     so that it pools and pairs with that seed of the other models
#   pool_tables NAME  pools A with the pairs P into runs/NAME/eval, shapes the pooled tables like the paper's
#                     (results/NAME/paper_tables.md) and copies the pooled tables into results/NAME/
export PATH=$PWD/.venv/bin:$PATH
A=()
P=()

add() {
  local file="results/$1/results.json" agent name
  while IFS= read -r agent; do
    name=$agent
    if [ -n "${3:-}" ] && [ "$agent" = "$2" ]; then name="$agent seed $3"; fi
    A+=(--agent "$name=$file:$agent")
  done < <(python - "$file" "$2" <<'PY'
import json, re, sys
path, model = sys.argv[1:]
for agent in json.load(open(path))["config"]["agents"]:
    if re.fullmatch(re.escape(model) + r"( seed \d+)?", agent):
        print(agent)
PY
  )
}

pool_tables() {
  local out="runs/$1/eval"
  rm -rf "runs/$1"
  veragmil-pool-results "$out" "${A[@]}" "${P[@]}"
  python results/grid_calibrated_tables/paper_tables.py "$out/seeds/table.csv" > "results/$1/paper_tables.md"
  cp -r "$out"/{table.md,table.csv,stages.md,stages.csv,seeds.md,seeds.csv,success.png,seeds,paired.md} "results/$1/"
}
