#!/usr/bin/env bash
# GPU check of the study on a CUDA machine (run from the repository root with .gpu/ carried):
#   bash scripts/gpu_check.sh
# .gpu/ (ignored, .git/info/exclude) holds site.tar.xz (the Python 3.12 packages the machine lacks:
# mitsuba (cuda_ad_rgb, llvm_ad_rgb, scalar_rgb), drjit, pyrender, PyOpenGL, ...), gl/*.deb
# (libglvnd's EGL/GL dispatch, unpacked only on a GPU machine) and ghost.toml (the ghosting study;
# scripts/gpu_ghost.toml where it has none).
# Steps, each with its own timeout and log under $OUT, continuing after a failure:
#   a smoke (variant, tiny Mitsuba render, one EGL raster frame of pipe)
#   b bench (one hairball_rotating_lit reference, cold and warm, and pipe, scripts/gpu_bench.py)
#   d the references' tests
#   c the ghosting study on sphere_ghosting, then on hairball_rotating_lit
# The packages: an offline bundle of wheels (scripts/gpu_bundle.py: build/gpu-bundle/, or its tarball
# gpu-bundle-*.tar; GPU_BUNDLE names either) installed with no package index (`uv pip install
# --no-index --find-links`, else pip's) into the interpreter; where there is none, .gpu/site.tar.xz.
# No CUDA device with a cuda_* TAA_VARIANT: refused at once, exit status 2 (a CPU rehearsal:
# TAA_VARIANT=llvm_ad_rgb GPU_CHECK_SMALL=1).
# Steps beside those: r the thesis profile's references for one scene (GPU_CHECK_SCENE, default pipe;
#   frames 0 and 1 at 1600x900, cold and warm, its [reference] settings) and Mitsuba's own
#   ray_intersect rate on that scene, beside the references' samples/s (scripts/gpu_bench.py --intersect)
# Knobs: TAA_VARIANT (default cuda_ad_rgb), GPU_CHECK_SMALL=1 (160x90, fewer frames: a CPU test),
# GPU_CHECK_WIDTH/HEIGHT, GPU_CHECK_FRAMES (sphere's ghosting frames), GPU_CHECK_FRAMES_C2 (hairball's, 24), GPU_CHECK_STEPS (default "a r b d c1 c2"),
# T_A T_R T_B T_D T_C1 T_C2 (seconds per step), GPU_CHECK_SITE (where the packages go), GPU_BUNDLE,
# GPU_CHECK_PACKAGES=installed (the interpreter's own packages: a rehearsal).
set -u
cd "$(dirname "$0")/.."
ROOT=$PWD
OUT=${OUT:-/tmp/gpu_out}
mkdir -p "$OUT"
LOG=$OUT/gpu_check.log
exec > >(tee -a "$LOG") 2>&1
stamp() { echo "=== $(date +%s) $(date -u +%H:%M:%S) $*"; }
stamp "gpu_check start in $ROOT, OUT=$OUT"

PY=${PYTHON:-python3}
export TAA_VARIANT=${TAA_VARIANT:-cuda_ad_rgb}
# a CUDA variant needs a CUDA device: refused before anything is unpacked or installed
case "$TAA_VARIANT" in cuda_*)
    if ! nvidia-smi -L 2>/dev/null | grep -q '^GPU '; then
        echo "gpu_check: no CUDA device (nvidia-smi lists no GPU) for TAA_VARIANT=$TAA_VARIANT; run it on a CUDA" \
             "machine, or rehearse on a CPU with TAA_VARIANT=llvm_ad_rgb GPU_CHECK_SMALL=1" >&2
        exit 2
    fi;;
esac
export HOME=/tmp/home PYTHONUNBUFFERED=1 PYOPENGL_PLATFORM=egl PYGLET_HEADLESS=1 TAA_STUDY_WORKERS=1
# a cache of its own: never the checkout's .cache (cold references, honest timings)
export TAA_STUDY_CACHE=${GPU_CHECK_CACHE:-/tmp/taa-cache-gpu-check}
mkdir -p "$HOME"
SMALL=${GPU_CHECK_SMALL:-0}
if [ "$SMALL" = 1 ]; then W=${GPU_CHECK_WIDTH:-160}; H=${GPU_CHECK_HEIGHT:-90}; FR=${GPU_CHECK_FRAMES:-8}
else W=${GPU_CHECK_WIDTH:-1600}; H=${GPU_CHECK_HEIGHT:-900}; FR=${GPU_CHECK_FRAMES:-100}; fi
STEPS=${GPU_CHECK_STEPS:-"a r b d c1 c2"}

# --- GL (libglvnd) on a GPU machine: the driver mounts libEGL_nvidia but not the dispatch library
if command -v nvidia-smi >/dev/null 2>&1; then
    stamp "nvidia-smi"
    nvidia-smi || true
    echo "--- /usr/local/nvidia/lib64 (optix, cuda):"
    ls /usr/local/nvidia/lib64 2>&1 | grep -i -e optix -e cuda || echo "NO optix/cuda libraries listed"
    ls /usr/local/nvidia/lib64 2>/dev/null | grep -q 'libnvoptix.so.1' && echo "OPTIX: libnvoptix.so.1 present" \
        || echo "OPTIX: libnvoptix.so.1 MISSING (Mitsuba's cuda variants will fail)"
    export LD_LIBRARY_PATH=/usr/local/nvidia/lib64${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
    if [ "$(id -u)" = 0 ] && ls .gpu/gl/*.deb >/dev/null 2>&1; then
        for f in .gpu/gl/*.deb; do dpkg -x "$f" / || echo "dpkg -x $f failed"; done
        ldconfig || true
    fi
    echo "--- EGL vendor files:"
    ls /usr/share/glvnd/egl_vendor.d /etc/glvnd/egl_vendor.d /usr/local/nvidia/share/glvnd/egl_vendor.d 2>&1
    if ! ls /usr/share/glvnd/egl_vendor.d/*nvidia*.json /etc/glvnd/egl_vendor.d/*nvidia*.json >/dev/null 2>&1; then
        for j in /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json /usr/local/nvidia/lib64/10_nvidia.json; do
            [ -f "$j" ] && { export __EGL_VENDOR_LIBRARY_FILENAMES=$j; break; }
        done
        if [ -z "${__EGL_VENDOR_LIBRARY_FILENAMES:-}" ]; then   # write one: the driver's libEGL_nvidia
            mkdir -p /tmp/egl_vendor.d
            printf '{"file_format_version":"1.0.0","ICD":{"library_path":"libEGL_nvidia.so.0"}}\n' \
                > /tmp/egl_vendor.d/10_nvidia.json
            export __EGL_VENDOR_LIBRARY_FILENAMES=/tmp/egl_vendor.d/10_nvidia.json
        fi
    fi
    echo "__EGL_VENDOR_LIBRARY_FILENAMES=${__EGL_VENDOR_LIBRARY_FILENAMES:-(default search)}"
    ldconfig -p 2>/dev/null | grep -i -e 'libEGL' -e 'libnvoptix' -e 'libcuda.so' || true
else
    stamp "no nvidia-smi: no GPU; GL debs not unpacked"
fi

# --- the packages: the offline bundle of wheels where there is one (scripts/gpu_bundle.py), else
# .gpu/site.tar.xz unpacked into a folder under the interpreter's site-packages, named by a .pth
# file (provenance treats modules outside stdlib/site-packages as the project's own and walks them)
PURELIB=$($PY -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
SITE=${GPU_CHECK_SITE:-$PURELIB/_gpu_site}
BUNDLE=${GPU_BUNDLE:-}
if [ -z "$BUNDLE" ]; then
    for b in build/gpu-bundle .gpu/gpu-bundle build/gpu-bundle-*.tar .gpu/gpu-bundle-*.tar; do
        [ -e "$b" ] && { BUNDLE=$b; break; }
    done
fi
if [ "${GPU_CHECK_PACKAGES:-}" = installed ]; then   # a rehearsal with the interpreter's own packages
    stamp "packages: $PY's own (GPU_CHECK_PACKAGES=installed)"
    export PYTHONPATH=$ROOT
elif [ -n "$BUNDLE" ] && [ -f "$BUNDLE" ]; then      # the tarball: unpacked beside the others
    mkdir -p /tmp/gpu-bundle-x && tar -C /tmp/gpu-bundle-x -xf "$BUNDLE" && BUNDLE=$(ls -d /tmp/gpu-bundle-x/*/ | head -1)
fi
if [ "${GPU_CHECK_PACKAGES:-}" = installed ]; then
    :
elif [ -n "$BUNDLE" ]; then
    stamp "installing the bundle $BUNDLE offline (no package index)"
    [ -f "$BUNDLE/lock.txt" ] && [ -d "$BUNDLE/wheels" ] || { echo "gpu_check: $BUNDLE has no lock.txt or wheels/" >&2; exit 2; }
    if command -v uv >/dev/null 2>&1; then
        uv pip install --python "$PY" --no-index --find-links "$BUNDLE/wheels" -r "$BUNDLE/lock.txt" \
            || { echo "gpu_check: uv pip install from $BUNDLE failed" >&2; exit 2; }
    else
        $PY -m pip install --no-index --find-links "$BUNDLE/wheels" -r "$BUNDLE/lock.txt" \
            || { echo "gpu_check: pip install from $BUNDLE failed" >&2; exit 2; }
    fi
    export PYTHONPATH=$ROOT
    for d in "$BUNDLE"/gl/*.deb; do [ -f "$d" ] && [ "$(id -u)" = 0 ] && { dpkg -x "$d" / || echo "dpkg -x $d failed"; }; done
    ldconfig 2>/dev/null || true
else
stamp "unpacking .gpu/site.tar.xz"
if mkdir -p "$SITE" 2>/dev/null && [ -w "$PURELIB" ]; then
    [ -f "$SITE/.done" ] || { tar -C "$SITE" -xJf .gpu/site.tar.xz && touch "$SITE/.done"; }
    echo "$SITE" > "$PURELIB/_gpu_site.pth"
    export PYTHONPATH=$ROOT
else
    SITE=/tmp/site; mkdir -p $SITE; tar -C $SITE -xJf .gpu/site.tar.xz
    echo "WARNING: $PURELIB not writable; PYTHONPATH=/tmp/site (provenance will walk those packages)"
    export PYTHONPATH=/tmp/site:$ROOT
fi
du -sh "$SITE" 2>/dev/null
fi
$PY -V; $PY -c 'import numpy, scipy; print("numpy", numpy.__version__, "scipy", scipy.__version__)' 2>&1 | tail -1
$PY -c 'import torch; print("torch", torch.__version__, "cuda", torch.cuda.is_available())' 2>&1 | tail -1
echo "TAA_VARIANT=$TAA_VARIANT size ${W}x${H} ghosting frames $FR steps: $STEPS"

status=""
step() {   # name seconds command...: output live into the combined log
    local name=$1 secs=$2; shift 2
    stamp "step $name start (timeout ${secs}s): $*"
    local t0=$(date +%s%N)
    timeout -k 10 "$secs" "$@" 2>&1 | tee "/tmp/step_$name.log"
    local rc=${PIPESTATUS[0]}
    local ms=$(( ($(date +%s%N) - t0) / 1000000 ))
    [ "$rc" = 124 ] && rc="124(TIMEOUT)"
    stamp "step $name end rc=$rc wall=${ms}ms"
    status="$status $name:rc=$rc:${ms}ms"
}
has() { case " $STEPS " in *" $1 "*) return 0;; esac; return 1; }

SW=$W; SH=$H; [ "$SMALL" = 1 ] || { SW=320; SH=180; }
has a && step a "${T_A:-60}" $PY scripts/gpu_bench.py --smoke --scene pipe --width "$SW" --height "$SH"
has r && step r "${T_R:-240}" $PY scripts/gpu_bench.py --profile thesis --scene "${GPU_CHECK_SCENE:-pipe}" \
    --width "$W" --height "$H" --frames 0 1 --compare --intersect
has b && step b "${T_B:-90}" $PY scripts/gpu_bench.py --scene hairball_rotating_lit --width "$W" --height "$H" \
    --frames 0 1 --compare pipe
has d && step d "${T_D:-90}" $PY -m pytest -q -x tests/test_reference.py tests/test_reference_adaptive.py \
    tests/test_reference_held_out.py tests/test_reference_textured.py -p no:cacheprovider

GH=/tmp/ghost.toml
GHOST_SRC=.gpu/ghost.toml; [ -f "$GHOST_SRC" ] || GHOST_SRC=scripts/gpu_ghost.toml
sed -e "s/^frames = 100/frames = $FR/" "$GHOST_SRC" > $GH
[ "$SMALL" = 1 ] && sed -i 's/^metric = "cvvdp"/metric = "none"/' $GH     # a rehearsal: no JOD
[ "$SMALL" = 1 ] || [ -n "${GPU_CHECK_WIDTH:-}" ] && sed -i "s/^resolution = \"full\"/resolution = [$W, $H]/" $GH
for c in c1 c2; do
    has $c || continue
    scene=sphere_ghosting; secs=${T_C1:-120}
    [ $c = c2 ] && { scene=hairball_rotating_lit; secs=${T_C2:-60}; }
    rm -rf /tmp/gh_$c
    gh=$GH
    if [ $c = c2 ]; then   # hairball's references cost ~30x sphere's: fewer frames by default
        gh=/tmp/ghost_c2.toml
        sed -e "s/^frames = $FR\$/frames = ${GPU_CHECK_FRAMES_C2:-$(( FR < 24 ? FR : 24 ))}/" $GH > $gh
    fi
    grep -e '^resolution' -e '^frames' $gh
    step $c "$secs" $PY -m study run $gh --scenes $scene --workers 1 --out /tmp/gh_$c
    (cd /tmp/gh_$c 2>/dev/null && find . -type f | sort | head -60)
    tables=$(find /tmp/gh_$c -type f \( -path '*ghosting*' -o -name '*.md' \) \( -name '*.csv' -o -name '*.md' \) 2>/dev/null | sort)
    if [ -n "$tables" ]; then
        tar -czf "$OUT/tables_$c.tar.gz" $tables /tmp/gh_$c/*.json 2>/dev/null
        for t in $(echo "$tables" | grep -i ghost | head -4); do echo "----- $t"; head -40 "$t"; done
    fi
done
stamp "gpu_check done:$status"
