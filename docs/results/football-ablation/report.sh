#!/usr/bin/env bash
# Issue 65's report (docs/results/football-ablation.md: football 3 vs 1, which half of SAEIR leaves the floor earlier),
# run from the repository root:
#
#   bash docs/results/football-ablation/report.sh           # copy, then the page
#   bash docs/results/football-ablation/report.sh copy      # on the machine of the runs: the run files only
#   bash docs/results/football-ablation/report.sh bonus     # on the machine of the runs: bonus_rise.md (minutes)
#   bash docs/results/football-ablation/report.sh report    # the page, from the committed run files alone
#
# copy: from $HOME/saeir-results/football-ablation/runs/<algo>/grf-3v1-keeper_s<seed> (queue.sh's output) to
# runs/<algo>/grf-3v1-keeper_s<seed> here, with benchmarks/copy_run_files.py: spec.json, evaluations.csv,
# segments.json, resume.log, done.json (never checkpoints, models or progress.csv). A run still training is copied as
# far as it got (the page shows it as running, never as a final). A finished run with the SAEIR bonus also gets its
# bonus files from its progress.csv (bonus.md, bonus.png and bonus_by_250k.md, the fire rate and mean bonus per scale
# per 250k env steps): SAEIR_PPO through copy_run_files.py --bonus-window 250000 --bonus-name bonus_by_250k.md (as
# football-stage-f/report.sh), SAE-only through benchmarks/bonus_files.py with the same window and name
# (copy_run_files.py makes bonus files for SAEIR_PPO only). SAEIR_PPO seed 4 trains in legs, each ending with its
# done.json: its bonus files are rewritten at each copy after a leg.
# bonus: benchmarks/bonus_rise.py on SAEIR_PPO seed 4's four kept models (queue.sh keeps each leg's final model with its
# spec.json) and on the final model of each finished SAE-only run (the bonus on MAPPO's critic), two rollouts of the
# run's 8 games each, rollout seed 20000 (the script's default), 200-step windows:
#
#   python benchmarks/bonus_rise.py --rollouts 2 \
#       --model $HOME/saeir-results/football-ablation/kept-models/saeir_ppo_s4_{250,500,750,1000}k/grf-3v1-keeper.zip \
#       $HOME/saeir-results/football-ablation/runs/sae_only/grf-3v1-keeper_s{1,2,3}/grf-3v1-keeper.zip
#
# into bonus_rise.md here, under that command (the models that exist; no kept model: it stops; about 3 minutes per
# model). Models are not committed.
# report: benchmarks/football_ablation.py writes runs.md, success.md, reaches.md, rule.md and curves.png here from the
# committed run files (MAPPO and SAEIR_PPO seeds 1-3: the runs of football-probe/runs/<algo> and
# football-stage-f/3v1/runs/<algo>/grf-3v1-keeper_s<seed>, read to 1M env steps), and a placeholder bonus_rise.md
# where there is none, then benchmarks/results_pages.py copies the tables into the page's generated blocks. Runs not
# started or not finished are shown as such and the rule stays pending: the report never fails on them.
# runs/ is in .gitignore (for run folders made elsewhere): add the copied run files with git add -f.
set -euo pipefail
RESULTS="${ABLATION_RESULTS:-$HOME/saeir-results/football-ablation}"
DOCS="${ABLATION_DOCS:-docs}"
STUDY="$DOCS/results/football-ablation"
PY="${PYTHON:-python}"
TASK=grf-3v1-keeper
WINDOW=(250000 bonus_by_250k.md)

copy_runs() {
    local run algo target bonus
    for run in "$RESULTS"/runs/*/"${TASK}"_s*; do
        [ -f "$run/spec.json" ] && [[ "$run" != *.replaced-* ]] || continue
        algo="$(basename "$(dirname "$run")")"
        target="$STUDY/runs/$algo/$(basename "$run")"
        bonus=()
        if [ -f "$run/done.json" ] && [ "$algo" = saeir_ppo ]; then
            bonus=(--bonus-window "${WINDOW[0]}" --bonus-name "${WINDOW[1]}")
        fi
        "$PY" benchmarks/copy_run_files.py "$run" "$target" "${bonus[@]}"
        if [ -f "$run/done.json" ] && [ "$algo" = sae_only ]; then
            "$PY" benchmarks/bonus_files.py "$run" "$target" --window "${WINDOW[0]}" --name "${WINDOW[1]}"
        fi
    done
}

bonus_rise() {
    local k seed model models=() shown=() legs=() n_sae=0 tmp
    for k in 250 500 750 1000; do
        model="$RESULTS/kept-models/saeir_ppo_s4_${k}k/$TASK.zip"
        if [ -f "$model" ]; then models+=("$model"); legs+=("${k}k"); fi
    done
    if [ ${#models[@]} -eq 0 ]; then
        echo "report.sh bonus: no kept model yet under $RESULTS/kept-models (queue.sh keeps them)" >&2
        exit 1
    fi
    for seed in 1 2 3; do  # SAE-only's finished runs: their final model, the bonus without the hypergraph critic
        model="$RESULTS/runs/sae_only/${TASK}_s$seed/$TASK.zip"
        if [ -f "$model" ] && [ -f "$(dirname "$model")/done.json" ]; then models+=("$model"); n_sae=$((n_sae + 1)); fi
    done
    for model in "${models[@]}"; do shown+=("\$HOME/saeir-results/football-ablation/${model#"$RESULTS"/}"); done
    tmp="$(mktemp)"
    "$PY" benchmarks/bonus_rise.py --rollouts 2 --model "${models[@]}" --out "$tmp" > /dev/null
    {
        echo "\`python benchmarks/bonus_rise.py --rollouts 2 --model ${shown[*]}\`"
        echo
        echo "(SAEIR_PPO seed 4's final model of each leg finished so far, at ${legs[*]} env steps, and the final model"
        echo "(1M env steps) of the $n_sae finished SAE-only runs, each with its spec.json; two rollouts of the run's 8"
        echo "games per model, rollout seed 20000, 200-step windows; models are not committed):"
        echo
        cat "$tmp"
    } > "$STUDY/bonus_rise.md"
    rm -f "$tmp"
    cat "$STUDY/bonus_rise.md"
}

report() {
    "$PY" benchmarks/football_ablation.py --results "$DOCS/results"
    "$PY" benchmarks/results_pages.py --docs "$DOCS" --pages football-ablation
}

case "${1:-all}" in
    all) copy_runs; report ;;
    copy) copy_runs ;;
    bonus) bonus_rise ;;
    report) report ;;
    *) echo "usage: bash docs/results/football-ablation/report.sh [all|copy|bonus|report]" >&2; exit 2 ;;
esac
