#!/usr/bin/env bash
# Makes farm/.venv, the Python environment of the Ray driver (farm/ray_render.py), with the
# pinned Ray. Idempotent: a venv that already holds this Ray is left as it is. Needs python3
# (3.9 or later, with its venv module) and PyPI. Run it on the machine that runs the driver
# and on every Ray node (each node's `ray start` must be the same Ray version). With --tests, also
# kubernetes-validate (the Kubernetes recipe's test checks its YAML against the API schemas).
#   farm/setup.sh [--tests]   # then: farm/.venv/bin/python farm/ray_render.py --help
set -euo pipefail
cd "$(dirname "$0")"
RAY_VERSION=2.60.0
KUBERNETES_VALIDATE_VERSION=1.37.0
venv=.venv
want=("ray==$RAY_VERSION")
check="import ray; assert ray.__version__ == '$RAY_VERSION'"
if [ "${1:-}" = "--tests" ]; then
  want+=("kubernetes-validate==$KUBERNETES_VALIDATE_VERSION")
  check="$check; import importlib.metadata as m; assert m.version('kubernetes-validate') == '$KUBERNETES_VALIDATE_VERSION'"
fi

# One setup at a time: tests may call this concurrently.
exec 9>".venv.lock"
flock 9

if [ -x "$venv/bin/python" ] &&
  "$venv/bin/python" -c "$check" 2>/dev/null; then
  exit 0
fi
if ! python3 -c 'import venv, ensurepip' 2>/dev/null; then
  echo "farm/setup.sh: python3 lacks its venv/ensurepip modules (Debian: apt-get install python3-venv)" >&2
  exit 1
fi
echo "farm/setup.sh: installing ${want[*]} into farm/$venv" >&2
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
# A bounded install: without network pip fails after its retries rather than hanging.
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check --timeout 30 --retries 2 \
  "${want[@]}"
"$venv/bin/python" -c "import ray, yaml; print('farm/setup.sh: ray', ray.__version__, 'in farm/$venv')" >&2
