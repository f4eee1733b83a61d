#!/usr/bin/env bash
# The grounding stacks on one GPU (issue 49; docs/benchmarks.md, "Grounding on a GPU"): SAM3, OWLv2 + MobileSAM and
# Grounding DINO + MobileSAM in process (fp32; bf16 with a batch of 8 and served to 8 clients; bf16 + torch.compile),
# all with random weights, and the throughput of drive-nav on benchmark v1 with 16 workers beside one served SAM3
# (random weights, bf16; the workers ground with the embedded detector and send every frame to the server too:
# --detector-shadow-url). Every measurement is a drivenav command, each bounded by `timeout` and by the script's
# budget: stages that no longer fit are skipped and named in the summary, to be rerun by name.
#
#   bash scripts/h100_grounding.sh [--cpu] [--budget S] [--window S] [--serve-window S] [--workers N] [STAGE ...]
#
# STAGE: sam3-fp32 sam3-bf16 owlv2-fp32 owlv2-bf16 gdino-fp32 gdino-bf16 throughput serve-eval serve-eval-x2
# serve-eval-apexnav sam3-compile owlv2-compile gdino-compile (default: all, in this order; serve-eval: `drivenav bench
# eval-throughput`, SAM3 served to the workers with one model copy, -x2 with two, -apexnav to ApexNav's workers, five
# phrases a frame: episodes an hour, the frames a second sustained while every worker grounds, and where a step's
# time goes; each eval is stopped --serve-window S after it starts, 90 by default, its workers never out of episodes).
# --cpu: a dry run of the script itself on this machine's CPU with the tests' tiny models (no wheels, no compile
# stages unless named; a 40 s serve window). Issue 61's check, within one device call:
#   bash scripts/h100_grounding.sh --budget 560 sam3-bf16 serve-eval serve-eval-apexnav serve-eval-x2
# Writes every stage's JSON and log, env.json and summary.json to $OUT (default /tmp/h100-grounding); the summary
# table comes last on stdout, then issue 61's verdict for each serve-eval stage (its steady frames a second against
# the sam3-bf16 stage's batch-8 speed; an OVON val split's GPU-hours at that rate).
#
# On the GPU machine (no network): the wheels of what it lacks are in .whl/ (mobilesam-mirror, omegaconf, pyzmq,
# and scikit-fmm's source, built here with the C++ compiler: it publishes no wheels; `bash scripts/h100_wheels.sh`
# downloads them beforehand, and the device call carries the ignored folder: carry [".whl"]); numba's JIT serves
# the kernels (DRIVENAV_KERNELS=jit), its cache warmed by one short episode of each agent while the GPU stages run.
set -uo pipefail

CPU=0
BUDGET=""
WINDOW=""
SERVE_WINDOW=""
WORKERS=""
STAGES=()
while (($#)); do
    case "$1" in
    --cpu) CPU=1 ;;
    --budget) BUDGET=$2; shift ;;
    --window) WINDOW=$2; shift ;;
    --serve-window) SERVE_WINDOW=$2; shift ;;
    --workers) WORKERS=$2; shift ;;
    -h | --help) sed -n '2,26p' "$0"; exit 0 ;;
    -*) echo "h100_grounding: unknown option $1 (see --help)" >&2; exit 2 ;;
    *) STAGES+=("$1") ;;
    esac
    shift
done

OUT=${OUT:-/tmp/h100-grounding}
RUNS=$(mktemp -d /tmp/h100-grounding-runs.XXXX)  # run directories (traces): only their records are copied to $OUT
mkdir -p "$OUT"
START=$(date +%s)
export DRIVENAV_KERNELS=jit HF_HUB_OFFLINE=1 TRANSFORMERS_OFFLINE=1 TOKENIZERS_PARALLELISM=false PYTHONUNBUFFERED=1
ALL_STAGES=(sam3-fp32 sam3-bf16 owlv2-fp32 owlv2-bf16 gdino-fp32 gdino-bf16 throughput serve-eval serve-eval-x2
    serve-eval-apexnav sam3-compile owlv2-compile gdino-compile)

if ((CPU)); then
    PYTHON=${PYTHON:-$([ -x .venv/bin/python ] && echo .venv/bin/python || echo python3)}
    DEVICE=cpu WEIGHTS=--tiny BUDGET=${BUDGET:-900} WINDOW=${WINDOW:-40} WORKERS=${WORKERS:-2}
    SERVE_WINDOW=${SERVE_WINDOW:-40} PER_WORKER=8  # serve-eval episodes a worker: more than a window holds
    ((${#STAGES[@]})) || STAGES=("${ALL_STAGES[@]:0:10}")  # inductor on a 2-core CPU takes minutes a model
else
    PYTHON=${PYTHON:-python3}
    DEVICE=cuda WEIGHTS=--random-weights BUDGET=${BUDGET:-420} WINDOW=${WINDOW:-150} WORKERS=${WORKERS:-16}
    SERVE_WINDOW=${SERVE_WINDOW:-90} PER_WORKER=4
    ((${#STAGES[@]})) || STAGES=("${ALL_STAGES[@]}")
fi
DEADLINE=$((START + BUDGET))
export PYTHONPATH=/tmp/site:$PWD/src${PYTHONPATH:+:$PYTHONPATH}
: >"$OUT/stages.tsv"

say() { printf '[%4ds] %s\n' $(($(date +%s) - START)) "$*"; }

# -- setup: the carried wheels, scikit-fmm from its source, numba's cache --------------------------------------------
setup() {
    if ((!CPU)); then
        mkdir -p /tmp/site
        local wheel pip=(python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site)
        if ! "${pip[@]}" .whl/*.whl >"$OUT/setup.log" 2>&1; then  # one at a time: a wheel that fails spares the others
            for wheel in .whl/*.whl; do
                "${pip[@]}" "$wheel" >>"$OUT/setup.log" 2>&1 || say "setup: $wheel did not install (setup.log)"
            done
        fi
    fi
    if ! "$PYTHON" -c "import skfmm" 2>/dev/null; then
        build_skfmm >>"$OUT/setup.log" 2>&1 && say "setup: scikit-fmm built from its source" ||
            say "setup: scikit-fmm did not build (see setup.log): the throughput stage will fail"
    fi
    "$PYTHON" - >"$OUT/env.json" 2>>"$OUT/setup.log" <<'EOF'
import json, os, platform, subprocess
info = {"python": platform.python_version(), "cpus": os.cpu_count()}
for name in ("torch", "transformers", "timm", "numba", "numpy"):
    try:
        info[name] = __import__(name).__version__
    except Exception as error:  # a missing package is a fact worth recording
        info[name] = f"missing: {error}"
try:
    import torch
    info["cuda"] = torch.version.cuda
    info["gpu"] = torch.cuda.get_device_name(0) if torch.cuda.is_available() else None
except Exception as error:
    info["gpu"] = f"unknown: {error}"
try:
    info["nvidia_smi"] = subprocess.run(
        ["nvidia-smi", "--query-gpu=name,memory.total,driver_version", "--format=csv,noheader"],
        capture_output=True, text=True, timeout=20).stdout.strip()
except Exception:
    info["nvidia_smi"] = None
print(json.dumps(info))
EOF
    say "setup: $(cat "$OUT/env.json")"
    # numba compiles drive-nav's and ApexNav's kernels once into its cache (JIT mode) while the GPU stages run
    (
        for agent in drive-nav apexnav; do
            "$PYTHON" -m drivenav.cli eval --agent "$agent" --scenes procedural:1 --episodes 1 --max-steps 60 \
                --out "$RUNS/numba-warmup-$agent"
        done
    ) >"$OUT/numba-warmup.log" 2>&1 &
    WARMUP_PID=$!
}

warmed() {  # the evals that follow wait for numba's cache (else each worker compiles the kernels in its first steps)
    if [ -n "${WARMUP_PID:-}" ] && kill -0 "$WARMUP_PID" 2>/dev/null; then
        timeout 240 tail --pid="$WARMUP_PID" -f /dev/null
        say "numba's cache warmed by one episode of each agent (numba-warmup.log)"
    fi
}

build_skfmm() {
    local sdist src py_include np_include suffix
    sdist=$(ls .whl/scikit_fmm-*.tar.gz 2>/dev/null | head -1)
    [ -n "$sdist" ] || { echo "no scikit_fmm sdist in .whl/"; return 1; }
    src=$(mktemp -d)
    tar xzf "$sdist" -C "$src" && src=$(echo "$src"/scikit_fmm-*)
    py_include=$("$PYTHON" -c "import sysconfig; print(sysconfig.get_paths()['include'])")
    np_include=$("$PYTHON" -c "import numpy; print(numpy.get_include())")
    suffix=$("$PYTHON" -c "import sysconfig; print(sysconfig.get_config_var('EXT_SUFFIX'))")
    mkdir -p /tmp/site/skfmm && cp "$src"/skfmm/{__init__,pfmm,heap}.py /tmp/site/skfmm/
    local cxx=${CXX:-$(command -v g++ || command -v c++)}
    # the two extension modules of its meson.build, with its sources and include directories
    "$cxx" -O2 -shared -fPIC -I"$py_include" -I"$np_include" -I"$src/skfmm" "$src"/skfmm/{fmm,heap,base_marcher}.cpp \
        "$src"/skfmm/{distance_marcher,travel_time_marcher,extension_velocity_marcher}.cpp \
        -o "/tmp/site/skfmm/cfmm$suffix" &&
        "$cxx" -O2 -shared -fPIC -I"$py_include" -I"$src/skfmm" "$src"/skfmm/{pheap,heap}.cpp \
            -o "/tmp/site/skfmm/pheap$suffix" &&
        "$PYTHON" -c "import skfmm, numpy; skfmm.distance(numpy.ones((4, 4)) - 2 * numpy.eye(4))"
}

# -- one stage: a command bounded by its cap and by what is left of the budget ---------------------------------------
# record NAME RC WALL LIMIT NOTE
record() { printf '%s\t%s\t%s\t%s\t%s\n' "$@" >>"$OUT/stages.tsv"; }

limit_for() {  # limit_for CAP -> seconds the stage may take now (0: it does not fit)
    local left=$((DEADLINE - $(date +%s) - 5))
    local limit=$(($1 < left ? $1 : left))
    echo $((limit < 25 ? 0 : limit))
}

bench_stage() {  # bench_stage NAME CAP ARGS... (BENCH: the bench command, default grounder; STOP: the signal at the
    # cap, default TERM; a bench eval-throughput stopped so prints the figures of what ran and exits 130)
    local name=$1 cap=$2 bench=${BENCH:-grounder} limit t0 rc
    shift 2
    limit=$(limit_for "$cap")
    if ((limit == 0)); then
        say "$name: skipped (no time left in the ${BUDGET}s budget)"
        record "$name" skipped 0 0 "no time left"
        return
    fi
    say "$name: drivenav bench $bench $* (at most ${limit}s)"
    t0=$(date +%s)
    timeout -s "${STOP:-TERM}" -k 45 "$limit" "$PYTHON" -m drivenav.cli bench "$bench" --device "$DEVICE" $WEIGHTS \
        --json "$@" >"$OUT/$name.json" 2>"$OUT/$name.log"
    rc=$?
    ((rc == 130 || rc == 124)) && [ -n "${STOP:-}" ] && [ -s "$OUT/$name.json" ] && rc=0  # stopped at its window
    record "$name" "$rc" $(($(date +%s) - t0)) "$limit" "$*"
    ((rc == 0)) || say "$name: exit $rc ($( ((rc == 124)) && echo "timed out" || tail -n 1 "$OUT/$name.log"))"
}

run_bench() {  # run_bench STAGE (STACK-KIND)
    local args
    case "${1%-*}" in
    sam3) args=(--detector sam3) ;;
    owlv2) args=(--detector owlv2 --segmenter mobilesam) ;;
    gdino) args=(--detector grounding-dino --segmenter mobilesam) ;;
    esac
    case "${1##*-}" in
    fp32) bench_stage "$1" 75 "${args[@]}" --dtype float32 --frames 10 ;;
    bf16) bench_stage "$1" 100 "${args[@]}" --dtype bfloat16 --frames 10 --batch 8 --clients 8 --phrases 8 ;;
    compile) bench_stage "$1" 170 "${args[@]}" --dtype bfloat16 --compile --frames 10 ;;
    esac
}

# -- serve-eval: bench eval-throughput, SAM3 served (COPIES copies) to $WORKERS workers, $PER_WORKER episodes each -------
serve_eval() {  # serve_eval NAME COPIES [AGENT]: the eval stopped after $SERVE_WINDOW s with every worker still busy
    # (the bench's --window, from the eval's start; 60 s more for building the model and stopping, else SIGINT)
    warmed
    STOP=INT BENCH=eval-throughput bench_stage "$1" $((SERVE_WINDOW + 60)) --detector sam3 --batch 16 --copies "$2" \
        --workers "$WORKERS" --window "$SERVE_WINDOW" -- --agent "${3:-drive-nav}" --scenes procedural:16 \
        --episodes $((PER_WORKER * WORKERS)) --seed 2026
}

# -- throughput: 16 workers on v1 beside one served SAM3 ------------------------------------------------------------
throughput() {
    local dir=$OUT/throughput port=$((20000 + RANDOM % 20000)) limit window server sampler t0 t1 rc dtype
    limit=$(limit_for $((WINDOW + 150)))
    if ((limit == 0)); then
        say "throughput: skipped (no time left)"
        record throughput skipped 0 0 "no time left"
        return
    fi
    mkdir -p "$dir"
    warmed
    dtype=$( ((CPU)) && echo float32 || echo bfloat16)
    t0=$(date +%s)
    "$PYTHON" -m drivenav.cli serve grounder --detector sam3 $WEIGHTS --device "$DEVICE" --dtype "$dtype" \
        --batch "$WORKERS" --bind "tcp://127.0.0.1:$port" >"$dir/server.out" 2>"$dir/server.log" &
    server=$!
    while ! grep -q "serving the grounder" "$dir/server.out" 2>/dev/null; do
        if ! kill -0 "$server" 2>/dev/null || (($(date +%s) - t0 > 120)); then
            say "throughput: the grounder server did not start ($(tail -n 1 "$dir/server.log"))"
            kill "$server" 2>/dev/null
            record throughput failed $(($(date +%s) - t0)) "$limit" "server did not start"
            return
        fi
        sleep 1
    done
    say "throughput: $(head -n 1 "$dir/server.out")"
    window=$((limit - ($(date +%s) - t0) - 40))
    window=$((window < WINDOW ? window : WINDOW))
    say "throughput: drivenav eval --agent drive-nav on v1, $WORKERS workers, embedded detector + served SAM3, ${window}s"
    (while true; do
        printf '%s\t%s\n' "$(date +%s.%N)" "$(cat "$RUNS/throughput/episodes.jsonl" 2>/dev/null | wc -l)"
        sleep 2
    done) >"$dir/progress.tsv" &
    sampler=$!
    t1=$(date +%s.%N)
    timeout -s INT -k 30 "$window" "$PYTHON" -m drivenav.cli eval --agent drive-nav --scenes procedural:40,maps \
        --seed 2026 --episodes src/drivenav/data/benchmarks/v1.json.gz --workers "$WORKERS" --detector embedded \
        --detector-shadow-url "tcp://127.0.0.1:$port" --out "$RUNS/throughput" >"$dir/eval.out" 2>"$dir/eval.log"
    rc=$?
    ((rc == 124)) && rc=0  # stopped at the window's end: the finished episodes are kept
    printf '%s\t%s\n' "$(date +%s.%N)" "$(cat "$RUNS/throughput/episodes.jsonl" 2>/dev/null | wc -l)" \
        >>"$dir/progress.tsv"
    mkdir -p "$dir/run" && cp "$RUNS"/throughput/{episodes.jsonl,run.json,summary.json} "$dir/run/" 2>/dev/null
    kill "$sampler" 2>/dev/null
    echo "$t1" >"$dir/eval_start"
    kill "$server" 2>/dev/null
    timeout 15 tail --pid="$server" -f /dev/null || kill -9 "$server" 2>/dev/null
    record throughput "$rc" $(($(date +%s) - t0)) "$limit" "window ${window}s, $WORKERS workers"
    say "throughput: eval done (exit $rc; $(cat "$dir/run/episodes.jsonl" 2>/dev/null | wc -l) episodes finished)"
    rm -rf "$RUNS"
}

setup
for stage in "${STAGES[@]}"; do
    case "$stage" in
    throughput) throughput ;;
    serve-eval) serve_eval "$stage" 1 ;;
    serve-eval-x2) serve_eval "$stage" 2 ;;
    serve-eval-apexnav) serve_eval "$stage" 1 apexnav ;;
    sam3-* | owlv2-* | gdino-*) run_bench "$stage" ;;
    *) say "unknown stage $stage (one of ${ALL_STAGES[*]})"; record "$stage" unknown 0 0 "" ;;
    esac
done
[ -n "${WARMUP_PID:-}" ] && kill "$WARMUP_PID" 2>/dev/null

# -- summary: $OUT/summary.json, then the table ----------------------------------------------------------------------
OUT="$OUT" BUDGET="$BUDGET" START="$START" "$PYTHON" - <<'EOF'
import json, os, time
from pathlib import Path

out = Path(os.environ["OUT"])
stages = []
for line in (out / "stages.tsv").read_text().splitlines():
    name, rc, wall, limit, note = (line.split("\t") + [""] * 5)[:5]
    stage = {"stage": name, "rc": rc, "wall_s": int(wall or 0), "limit_s": int(limit or 0), "args": note}
    result = out / f"{name}.json"
    if result.is_file() and result.read_text().strip():
        try:
            stage["result"] = json.loads(result.read_text().strip().splitlines()[-1])
        except json.JSONDecodeError:
            stage["result"] = None
    stages.append(stage)


def throughput() -> dict:
    run = out / "throughput"
    episodes = run / "run" / "episodes.jsonl"
    if not (run / "eval_start").is_file():
        return {}
    records = [json.loads(line) for line in episodes.read_text().splitlines()] if episodes.is_file() else []
    samples = [tuple(map(float, line.split("\t"))) for line in (run / "progress.tsv").read_text().splitlines()]
    start, (end, finished) = float((run / "eval_start").read_text()), samples[-1]
    first = next(((t, n) for t, n in samples if n >= 1), None)
    steady = None
    if first is not None and end > first[0] and finished > first[1]:
        steady = round((finished - first[1]) / (end - first[0]) * 3600.0, 1)
    server = (run / "server.out").read_text().splitlines()
    return {
        "episodes_finished": int(finished),
        "eval_wall_s": round(end - start, 1),
        "episodes_per_hour": round(finished / (end - start) * 3600.0, 1) if end > start else None,
        "episodes_per_hour_after_first": steady,
        "first_episode_s": round(first[0] - start, 1) if first else None,
        "errors": sum(1 for r in records if r.get("stop_reason") == "error"),
        "success_rate": round(sum(r.get("success", 0) for r in records) / len(records), 3) if records else None,
        "steps_mean": round(sum(r.get("steps", 0) for r in records) / len(records), 1) if records else None,
        "server": server[0] if server else None,
        "served": server[-1] if len(server) > 1 else None,
    }


OVON_VAL_FRAMES = 900_000  # one HM3D-OVON val split: about 3,000 episodes of about 300 steps (docs/benchmarks.md)


def goals() -> list[dict]:
    """Issue 61's verdict for each served eval: the frames a second it sustained while every worker grounded (its
    steady rate; the eval's own rate, start-up and stop included, where it had no steady window) against SAM3 bf16's
    batch-8 speed (the sam3-bf16 stage of the same run; goal >= 80 %) and one OVON val split's GPU-hours at that
    rate (goal <= 3)."""
    reference = next((s["result"] for s in stages if s["stage"] == "sam3-bf16" and s.get("result")), None)
    batch8 = 1000.0 / reference["batch_ms_per_frame"] if reference and reference.get("batch_ms_per_frame") else None
    verdicts = []
    for stage in stages:
        result = stage.get("result") or {}
        steady = result.get("steady_frames_per_second")
        fps = steady or result.get("frames_per_second")
        if stage["stage"].startswith("serve-eval") and fps:
            share = round(fps / batch8, 3) if batch8 else None
            verdicts.append({"stage": stage["stage"], "frames_per_second": fps, "rate": "steady" if steady else "eval",
                             "eval_frames_per_second": result.get("frames_per_second"),
                             "batch8_frames_per_second": round(batch8, 2) if batch8 else None, "share_of_batch8": share,
                             "ovon_val_gpu_hours": round(OVON_VAL_FRAMES / fps / 3600.0, 2)})
    return verdicts


env = json.loads((out / "env.json").read_text() or "{}") if (out / "env.json").is_file() else {}
summary = {"env": env, "budget_s": int(os.environ["BUDGET"]), "wall_s": int(time.time()) - int(os.environ["START"]),
           "stages": stages, "throughput": throughput(), "goals": goals()}
(out / "summary.json").write_text(json.dumps(summary, indent=2))

cols = ("median_ms", "forward_ms", "segment_ms", "batch_ms_per_frame", "served_ms_per_frame", "served_overhead_ms",
        "detections_per_frame", "gpu_memory_mb")
print(f"\n== grounding on {env.get('gpu') or 'cpu'} (torch {env.get('torch')}, transformers {env.get('transformers')});"
      f" {summary['wall_s']} s of a {summary['budget_s']} s budget; JSON: {out / 'summary.json'}")
print(f"{'stage':<15}{'rc':>8}{'wall':>6}" + "".join(f"{c.replace('_ms', '').replace('_per_frame', '/f'):>16}" for c in cols))
for stage in stages:
    result = stage.get("result") or {}
    if "episodes_per_hour" in result:  # bench eval-throughput
        print(f"{stage['stage']:<15}{stage['rc']:>8}{stage['wall_s']:>6}  {result['episodes_per_hour']} episodes/h, "
              f"{result['frames_per_second']} frames/s (steady {result.get('steady_frames_per_second')} over "
              f"{result.get('steady_window_s')} s), mean batch {result['mean_batch']}, "
              f"{result.get('encodings_per_frame')} images encoded a frame, model busy "
              f"{result['model_busy']}, server ms a frame {result['server_stages_ms']}, a worker's step "
              f"{result['worker_step']}")
        continue
    cells = "".join(f"{'-' if result.get(c) is None else result[c]:>16}" for c in cols)
    print(f"{stage['stage']:<15}{stage['rc']:>8}{stage['wall_s']:>6}{cells}")
tp = summary["throughput"]
if tp:
    print(f"throughput: {tp['episodes_finished']} episodes in {tp['eval_wall_s']} s = {tp['episodes_per_hour']} "
          f"episodes/h ({tp['episodes_per_hour_after_first']} after the first, at {tp['first_episode_s']} s); "
          f"errors {tp['errors']}, SR {tp['success_rate']}, mean steps {tp['steps_mean']}; server {tp['served']}")
for goal in summary["goals"]:
    share = "-" if goal["share_of_batch8"] is None else f"{goal['share_of_batch8']:.0%}"
    print(f"issue 61, {goal['stage']}: {goal['frames_per_second']} frames/s ({goal['rate']}) = {share} of SAM3 bf16's batch-8 speed "
          f"({goal['batch8_frames_per_second']} frames/s, stage sam3-bf16; goal >= 80 %); one OVON val split "
          f"({OVON_VAL_FRAMES:,} frames) in {goal['ovon_val_gpu_hours']} GPU-hours (goal <= 3)")
skipped = [s["stage"] for s in stages if s["rc"] != "0"]
if skipped:
    print(f"not completed (rerun by name: bash scripts/h100_grounding.sh {' '.join(skipped)}): {', '.join(skipped)}")
EOF
