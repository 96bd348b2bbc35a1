#!/usr/bin/env bash
# Regenerates the regression fixtures under fixtures/ and blesses their
# expectations. Each fixture is a directory with dump.pds, a reference
# (reference.exr, or reference_0000.exr, … for an animation), manifest.json
# (what it shows, the configuration, the expectations) and expected/*.exr.
#
# Renderer fixtures: every scene at 32 × 32, 8 spp, pixel-major, reference
# at 256 spp; the glossy room also pass-major; the moving scene 24 × 24,
# 4 frames, 4 spp. One synthetic fixture (64 × 64, 16 spp, 1% fireflies, a
# 3 × 3-pixel light), whose reference is the firefly-free field at 1024 spp.
#
# Each runs the paper's filter (FilterConfig::PAPER); four more (NAME-default:
# a still pixel-major and a pass-major scene, the animation, the synthetic
# field) run the shipped defaults on the same dump and reference. Every
# fixture makes every method this build can (all but the OIDN ones); bless
# writes the whole configuration into the manifest, so a later change of a
# default shows as drift.
#
#     bash tools/maint/make_fixtures.sh [ROOT]    # ROOT: fixtures (the checked-in ones)
set -euo pipefail
cd "$(dirname "$0")/../.."
root=${1:-fixtures}
cargo build --release --quiet
render=target/release/render
pd=target/release/pathdensity
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

methods='["mean", "filtered", "median", "trimmed", "bilateral", "median3", "filtered_bilateral", "mon", "gmon", "rwmc", "filtered_energy", "clamp", "filtered_energy_bilateral_ci", "guided", "statmc"]'
paper='"k": 10, "sigma_color": 100.0, "color_space": "cielab", "final_pass": "stored", "white": 1.0'

manifest() { # DIR DESCRIPTION REFERENCE
    cat >"$1/manifest.json" <<JSON
{ "description": "$2", "dump": "dump.pds", "reference": "$3",
  "config": { $paper, "methods": $methods } }
JSON
}

# NAME-default: the fixture NAME's dump and reference under the defaults.
defaults() { # NAME
    local d=$root/$1-default src=$root/$1
    rm -rf "$d"; mkdir -p "$d"
    local description
    description=$(grep -m1 '"description"' "$src/manifest.json" | sed 's/^.*"description": "\([^"]*\)".*$/\1/')
    cat >"$d/manifest.json" <<JSON
{ "description": "the defaults on ../$1's dump: $description", "dump": "../$1/dump.pds", "reference": "../$1/reference.exr",
  "config": { "methods": $methods } }
JSON
}

scene() { # NAME SCENE ORDER SIZE SPP FRAMES DESCRIPTION
    local d=$root/$1
    rm -rf "$d"; mkdir -p "$d"
    $render --scene "$2" --order "$3" --width "$4" --height "$4" --spp "$5" \
        --frames "$6" -o "$d/dump.pds" --reference-spp 256 \
        --reference-out "$d/reference.exr" >/dev/null
    manifest "$d" "$7" reference.exr
}

scene glossy-room glossy-room pixel 32 8 1 "render --scene glossy-room, 32x32, 8 spp, pixel-major, seed 1; reference 256 spp"
scene glossy-room-pass glossy-room pass 32 8 1 "render --scene glossy-room, 32x32, 8 spp, pass-major, seed 1; reference 256 spp"
scene diffuse-room diffuse-room pixel 32 8 1 "render --scene diffuse-room, 32x32, 8 spp, pixel-major, seed 1; reference 256 spp"
scene two-lights two-lights pixel 32 8 1 "render --scene two-lights, 32x32, 8 spp, pixel-major, seed 1; reference 256 spp"
scene indirect-room indirect-room pixel 32 8 1 "render --scene indirect-room, 32x32, 8 spp, pixel-major, seed 1; reference 256 spp"
scene sky sky pixel 32 8 1 "render --scene sky, 32x32, 8 spp, pixel-major, seed 1; reference 256 spp"
scene moving moving pixel 24 4 4 "render --scene moving, 24x24, 4 frames, 4 spp, pixel-major, seed 1; reference 256 spp per frame"

d=$root/synth-demo
rm -rf "$d"; mkdir -p "$d"
$pd synth -o "$d/dump.pds" --width 64 --height 64 --spp 16 \
    --fireflies 0.01 --light 30,20,3,20 --seed 1 >/dev/null
$pd synth -o "$tmp/ref.pds" --width 64 --height 64 --spp 1024 \
    --fireflies 0 --light 30,20,3,20 --seed 2 >/dev/null
$pd filter "$tmp/ref.pds" -o "$tmp/ref" --methods mean --no-html >/dev/null
cp "$tmp/ref/mean.exr" "$d/reference.exr"
manifest "$d" "pathdensity synth 64x64, 16 spp, 1% fireflies, light 30,20,3,20, seed 1; reference: the firefly-free field at 1024 spp, seed 2" reference.exr

for name in glossy-room glossy-room-pass moving synth-demo; do defaults $name; done

$pd regress "$root" --bless
du -sh "$root"
