#!/usr/bin/env bash
# Install Google Research Football (gfootball 2.10.2) into the project venv, for the grf-* tasks.
#
#   bash scripts/install_football.sh                  # into .venv (created if missing)
#   bash scripts/install_football.sh --venv /tmp/env  # another venv (created if missing; relative paths: to the repo)
#
# Steps (each skipped when already done, so a second run takes a few seconds):
#   1. apt (as root, or through sudo): the engine's build dependencies (SDL2, Boost.Python and friends, ~240 MB).
#   2. the `football` extra of setup.cfg (gym==0.23.1, six, opencv-python, psutil, wheel, ...), torch constrained to
#      2.13.0 (what `pip install 'sb3-saeir[football]'` installs, without reinstalling the package).
#   3. `pip install --no-build-isolation --no-deps gfootball==2.10.2` with the venv's bin/ first on PATH. gfootball
#      ships only an sdist whose C++ engine build (6-15 min on 2 cores) calls a bare `python3 -c 'import psutil'`
#      and declares no build requirements, so neither pip's isolated build nor a non-activated venv works. pip caches
#      the built wheel (~32 MB), so a reinstall on the same machine takes seconds.
#      --no-deps: gfootball requires pygame, which would overwrite pygame-ce (mpe2 needs it; both provide `pygame`);
#      gfootball only uses pygame for human play.
#   4. a smoke test: create academy_3_vs_1_with_keeper and step it.
#
# It does not install sb3-saeir itself: use scripts/install.sh for that (before or after).
set -euo pipefail
cd "$(dirname "$0")/.."
REPO_ROOT="$(pwd)"
VENV=".venv"
while [ $# -gt 0 ]; do
    case "$1" in
        --venv) VENV="$2"; shift 2 ;;
        -h|--help) sed -n '2,19p' "$0"; exit 0 ;;
        *) echo "unknown argument: $1 (usage: bash scripts/install_football.sh [--venv PATH])" >&2; exit 2 ;;
    esac
done
GFOOTBALL_VERSION="2.10.2"
PYTHON="${PYTHON:-python3}"
APT_PACKAGES=(
    build-essential cmake python3-dev
    libsdl2-dev libsdl2-image-dev libsdl2-ttf-dev libsdl2-gfx-dev
    libboost-python-dev libboost-thread-dev libboost-system-dev libboost-filesystem-dev
    libgl-dev libegl-dev
)
SMOKE_TEST='
import gfootball.env as football_env
env = football_env.create_environment(
    env_name="academy_3_vs_1_with_keeper", representation="simple115v2", rewards="scoring",
    number_of_left_players_agent_controls=3, render=False)
obs = env.reset()
assert obs.shape == (3, 115), obs.shape
env.step([0, 0, 0])
env.close()
'
pip_install() {
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -c "$constraints" "$@"
}

if [ ! -x "$VENV/bin/python" ]; then
    echo "== creating $VENV"
    "$PYTHON" -m venv "$VENV"
fi
VENV="$(cd "$VENV" && pwd)"

# Fast path: engine importable, right gym, smoke test passes -> nothing to do.
if "$VENV/bin/python" -c "import gym, six; assert int(gym.__version__.split('.')[1]) < 26; $SMOKE_TEST" >/dev/null 2>&1; then
    echo "gfootball $("$VENV/bin/python" -m pip show gfootball 2>/dev/null | sed -n 's/^Version: //p') already works in $VENV"
    exit 0
fi

start=$(date +%s)
missing=()
for package in "${APT_PACKAGES[@]}"; do
    dpkg -s "$package" >/dev/null 2>&1 || missing+=("$package")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "== apt: ${missing[*]}"
    SUDO=""
    if [ "$(id -u)" -ne 0 ]; then
        if command -v sudo >/dev/null 2>&1; then
            SUDO="sudo"
        else
            echo "Missing apt packages (${missing[*]}): run this script as root or install them first." >&2
            exit 1
        fi
    fi
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get update -q
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${APT_PACKAGES[@]}"
fi

constraints="$(mktemp)"
trap 'rm -f "$constraints"' EXIT
echo "torch==2.13.0" >"$constraints"  # never let the football deps move torch (see README)

# The extra first: it brings the build's own needs (psutil, wheel) and what `import gfootball.env` needs (gym, six).
echo "== the football extra"
mapfile -t extra < <("$VENV/bin/python" - "$REPO_ROOT/setup.cfg" <<'EOF'
import configparser
import sys

config = configparser.ConfigParser()
config.read(sys.argv[1])
print("\n".join(config["options.extras_require"]["football"].split()))
EOF
)
pip_install "${extra[@]}"

installed="$("$VENV/bin/python" -m pip show gfootball 2>/dev/null | sed -n 's/^Version: //p' || true)"
if [ "$installed" != "$GFOOTBALL_VERSION" ] || ! "$VENV/bin/python" -c "import gfootball.env" >/dev/null 2>&1; then
    echo "== gfootball $GFOOTBALL_VERSION (from source: 6-15 min on 2 cores; seconds from pip's wheel cache)"
    # The build script runs a bare `python3` that must see psutil: the venv's bin/ goes first on PATH.
    (
        export PATH="$VENV/bin:$PATH" VIRTUAL_ENV="$VENV"
        pip_install --no-build-isolation --no-deps --force-reinstall "gfootball==$GFOOTBALL_VERSION"
    )
fi

echo "== smoke test"
"$VENV/bin/python" -c "$SMOKE_TEST"
echo "gfootball $GFOOTBALL_VERSION works in $VENV ($(( $(date +%s) - start )) s)"
