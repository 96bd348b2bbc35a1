#!/usr/bin/env python3
"""Render a Mitsuba 3 scene with Mitsuba's own film (`mi.render`) to an EXR.

    render_film.py SCENE.xml -o OUT.exr --spp N [--seed S] [--size WxH] [--variant V]

The same scene loading as export.py (so --size means the same). With a box
reconstruction filter on the film, its pixels are the per-pixel means of
independent camera samples: what a dump of the same scene averages to, which
is how tests/mitsuba.rs checks the exporter against Mitsuba itself.
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import export  # noqa: E402


def main(argv):
    p = argparse.ArgumentParser(prog="render_film.py", description=__doc__.split("\n\n")[0])
    p.add_argument("scene")
    p.add_argument("-o", "--out", required=True)
    p.add_argument("--spp", type=export.positive, required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--size", type=export.parse_size)
    p.add_argument("--variant", default="llvm_ad_rgb")
    args = p.parse_args(argv)
    try:
        export.check_outputs([args.scene], [(args.out, "exr")])
        mi, _ = export.load_mitsuba(args.variant, None)
        scene = export.load_scene(mi, args.scene, args.size)
        export.check_scene(mi, args.scene, scene)
        image = mi.render(scene, spp=args.spp, seed=args.seed)
        export.exrio.write_rgb(args.out, export.np.asarray(image, dtype=export.np.float32)[:, :, :3])
    except export.ExportError as e:
        print(f"render_film.py: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
