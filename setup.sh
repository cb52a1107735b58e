#!/usr/bin/env bash
# Set up ITA (SWI-Prolog, a virtual environment, the package) and run something.
#
#   bash setup.sh run [ARGS]    set up, then run the main job (`ita inspect`: the whole bulkhead)
#   bash setup.sh test [ARGS]   set up (also Chromium for the browser tests), then run every test (pytest; ARGS go to pytest)
#   bash setup.sh setup         set up only
#
# Idempotent: when everything is in place it only checks, which takes about a second.
# Environment: ITA_VENV (default .venv beside this file), PYTHON (default python3.11 or python3).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
root=$(pwd)
venv=${ITA_VENV:-$root/.venv}
action=${1:-run}
[ $# -gt 0 ] && shift

say() { printf '[setup] %s\n' "$*" >&2; }

as_root() {
    if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi
}

apt_install() {
    say "installing Debian packages: $*"
    as_root env DEBIAN_FRONTEND=noninteractive apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null
}

find_python() {
    if [ -n "${PYTHON:-}" ]; then echo "$PYTHON"; return; fi
    for p in python3.11 python3; do
        if command -v "$p" >/dev/null 2>&1 &&
           "$p" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; then
            echo "$p"; return
        fi
    done
    say "Python 3.11 or newer is required (set PYTHON=/path/to/python3.11)"; exit 1
}

setup() {
    # SWI-Prolog; bubblewrap and libseccomp confine the knowledge-base query child
    # (ita/logic/confine.py: `ita kb query` refuses to run without them)
    local debs=()
    command -v swipl >/dev/null 2>&1 || debs+=(swi-prolog-nox)
    command -v bwrap >/dev/null 2>&1 || debs+=(bubblewrap)
    compgen -G '/usr/lib/*/libseccomp.so.2' >/dev/null || compgen -G '/lib/*/libseccomp.so.2' >/dev/null ||
        debs+=(libseccomp2)
    if [ ${#debs[@]} -gt 0 ]; then
        apt_install "${debs[@]}"
    fi
    local py; py=$(find_python)
    if ! "$venv/bin/python" -m pip --version >/dev/null 2>&1; then
        rm -rf "$venv"      # absent, or left half-made by an earlier failed attempt
        say "creating virtual environment $venv"
        if ! "$py" -m venv "$venv" >/dev/null 2>&1; then
            # Debian splits venv/ensurepip into its own package.
            rm -rf "$venv"
            apt_install "python3-venv" "$(basename "$py")-venv" || apt_install python3-venv
            "$py" -m venv "$venv"
        fi
    fi
    # Reinstall only when the package's metadata changed (source edits are live: editable install).
    local stamp="$venv/.ita-installed" want
    want=$( (cat pyproject.toml; "$venv/bin/python" --version) | sha256sum | cut -d' ' -f1)
    if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ] ||
       ! "$venv/bin/python" -c 'import ita, pyswip' 2>/dev/null; then
        say "installing the ita package and its test extras into $venv"
        "$venv/bin/python" -m pip install -q --upgrade pip
        "$venv/bin/python" -m pip install -q -e ".[test]"
        echo "$want" > "$stamp"
    fi
    # Compile the numba kernels again when their sources or the installed packages changed
    # (numba's cache lies beside the sources), so that the first run after a fresh set-up or
    # an update does not pay for it.  A failed warm-up only costs that first run its time.
    local kernels="$venv/.ita-kernels" have
    have=$( (echo "$want"; grep -rl --include='*.py' '@njit' ita | LC_ALL=C sort | xargs cat ita/warmup.py) |
            sha256sum | cut -d' ' -f1)
    if [ ! -f "$kernels" ] || [ "$(cat "$kernels")" != "$have" ]; then
        if "$venv/bin/python" -m ita.warmup >&2; then
            echo "$have" > "$kernels"
        else
            say "compiling the kernels ahead failed (a first run compiles what it needs)"
        fi
    fi
}

setup_browser() {
    # the browser tests of `ita serve` drive Debian's Chromium headless (not needed to run ITA)
    if ! command -v chromium >/dev/null 2>&1 || ! command -v chromedriver >/dev/null 2>&1; then
        apt_install chromium chromium-driver
    fi
}

setup
[ "$action" = test ] && setup_browser
case "$action" in
    setup) say "ready: $venv/bin/ita" ;;
    run)   exec "$venv/bin/ita" inspect "$@" ;;
    test)
        set +e
        # two workers (pytest-xdist), each file's tests on one of them (module fixtures and a
        # plunit file run once); `-n 0` runs them in this process
        "$venv/bin/python" -m pytest -n 2 --dist loadfile "$@"
        rc=$?
        # pytest exits 5 when no test was collected: that is a failure for us too.
        exit $rc ;;
    *) say "unknown action '$action' (use: run, test or setup)"; exit 2 ;;
esac
