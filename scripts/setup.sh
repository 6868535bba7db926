#!/usr/bin/env bash
# Installs what kdtrace needs on a fresh Debian/Ubuntu machine: the pinned nightly that rust-gpu
# 0.11 requires, the SPIR-V tools rust-gpu links against, and Mesa's lavapipe (a Vulkan device on
# the CPU) so the GPU path runs even where no GPU is attached. With --tests, also what the test
# suite needs beyond that: Debian's chromium, Node.js and npm (the web UI's browser test drives
# chromium through npm's playwright-core, installed into tests/web), and iproute2 (the server
# tests run in network namespaces of their own), and farm/.venv for the farm tests. Idempotent.
set -euo pipefail
cd "$(dirname "$0")/.."
tests=0
if [ "${1:-}" = "--tests" ]; then tests=1; fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

need_apt=()
command -v spirv-opt >/dev/null 2>&1 || need_apt+=(spirv-tools)
# The nv-flip crate compiles NVIDIA's ꟻLIP C++ (kdtrace compare).
command -v c++ >/dev/null 2>&1 || need_apt+=(g++)
# lavapipe: only needed where no Vulkan driver is installed, harmless beside a real one.
ls /usr/share/vulkan/icd.d/lvp_icd*.json >/dev/null 2>&1 || need_apt+=(mesa-vulkan-drivers)
ldconfig -p 2>/dev/null | grep -q 'libvulkan.so.1' || need_apt+=(libvulkan1)
if [ $tests = 1 ]; then
  [ -x /usr/lib/chromium/chromium ] || need_apt+=(chromium)
  command -v node >/dev/null 2>&1 || need_apt+=(nodejs)
  command -v npm >/dev/null 2>&1 || need_apt+=(npm)
  command -v ip >/dev/null 2>&1 || need_apt+=(iproute2)
  command -v unshare >/dev/null 2>&1 || need_apt+=(util-linux)
  # farm/setup.sh makes a venv (python3 -m venv).
  python3 -c 'import venv, ensurepip' >/dev/null 2>&1 || need_apt+=(python3 python3-venv)
fi
if [ ${#need_apt[@]} -gt 0 ]; then
  echo "setup: installing ${need_apt[*]}" >&2
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

toolchain=$(sed -n 's/^channel *= *"\(.*\)"/\1/p' rust-toolchain.toml)
components=(rust-src rustc-dev llvm-tools rustfmt clippy)
if ! rustup run "$toolchain" rustc --version >/dev/null 2>&1; then
  echo "setup: installing Rust $toolchain" >&2
  rustup toolchain install "$toolchain" --profile minimal --component "$(IFS=,; echo "${components[*]}")"
fi
installed=$(rustup component list --toolchain "$toolchain" --installed 2>/dev/null)
for c in "${components[@]}"; do
  if ! grep -q "^$c" <<<"$installed"; then
    echo "setup: adding $c to Rust $toolchain" >&2
    rustup component add --toolchain "$toolchain" "$c"
  fi
done

# The farm tests (tests/farm.rs): farm/.venv with the pinned Ray and kubernetes-validate. Bounded;
# where PyPI cannot be reached those tests print why and skip, so this does not fail the setup.
if [ $tests = 1 ] && ! timeout 900 farm/setup.sh --tests; then
  echo "setup: farm/setup.sh --tests failed: tests/farm.rs's Ray and Kubernetes tests will skip" >&2
fi

if [ $tests = 1 ] && [ ! -d tests/web/node_modules/playwright-core ]; then
  echo "setup: installing playwright-core into tests/web" >&2
  (cd tests/web && npm ci --no-audit --no-fund --loglevel=error)
fi
