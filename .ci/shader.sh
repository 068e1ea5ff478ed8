#!/usr/bin/env bash
# The exported shaders against the core on a Vulkan adapter: installs Mesa lavapipe (software Vulkan)
# and the Khronos validators where apt-get can, then runs nbrdf-shader's tests with the `gpu` feature.
# Without an adapter the values test prints SKIPPED with the reason; it never passes silently.
set -euo pipefail
cd "$(dirname "$0")/.."

if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    if ! dpkg -s mesa-vulkan-drivers glslang-tools spirv-tools >/dev/null 2>&1; then
        (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
            mesa-vulkan-drivers libvulkan1 glslang-tools spirv-tools >/dev/null) \
            || echo "SKIPPED: could not install mesa-vulkan-drivers (lavapipe) or the validators"
    fi
else
    echo "SKIPPED: no apt-get as root here: lavapipe and the validators are used only if already installed"
fi

# lavapipe wants a runtime directory for its shader cache; any writable one will do.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
cargo test -p nbrdf-shader --features gpu --test values --test export -- --nocapture 2>&1 \
    | grep -vE '^\s+(Compiling|Downloaded|Downloading)' 
exit "${PIPESTATUS[0]}"
