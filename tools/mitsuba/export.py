#!/usr/bin/env python3
"""Export a Mitsuba 3 scene's camera samples as a pathdensity dump (.pds).

    export.py SCENE.xml -o OUT.pds --spp N [--seed S] [--order pixel|pass]
              [--size WxH] [--variant V] [--threads T]
              [--reference-spp M --reference-out REF.exr]
              [--albedo-out A.exr] [--normal-out N.exr] [--aux-spp K]

Each record is one camera sample: the film position its ray was generated
from (pixels, row 0 at the top, relative to the film's crop window), t = the
normalised shutter time (0 for a still), and the unclamped linear RGB that
one path carried, camera weight included -- what `mi.render` would have
splatted. `mi.render` itself cannot give this: it splats into the film.

The loop follows Mitsuba's own SamplingIntegrator::render_sample with the
independent sampler: positions and values are generated a chunk of passes at
a time (every pixel of the film, `passes_per_chunk` passes), each chunk
seeded from (seed, chunk), so the same arguments give the same bytes for any
thread count. The reference (`--reference-out`) is the per-pixel mean of
M samples from the same loop with an independent seed: the box
reconstruction that `pathdensity filter --recon box` uses. The albedo and
normal (`--albedo-out`, `--normal-out`) come from Mitsuba's `aov`
integrator on the same film: OIDN's auxiliary inputs, for `pathdensity
filter --albedo A.exr --normal N.exr`.
"""

import argparse
import os
import sys
import time
import xml.etree.ElementTree as ET

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import exrio  # noqa: E402
import pds  # noqa: E402
from exporter import ExportError, Progress, check_outputs, parse_size, positive  # noqa: E402

PROG = "export.py"
SUPPORTED_INTEGRATORS = ("path", "volpath")
SAMPLES_PER_CHUNK = 1 << 20
DUMP_STREAM, REFERENCE_STREAM = 0, 1


def arguments(argv):
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0])
    p.add_argument("scene", help="a Mitsuba 3 scene file (.xml)")
    p.add_argument("-o", "--out", required=True, help="the dump to write (.pds)")
    p.add_argument("--spp", type=positive, required=True, help="samples per pixel")
    p.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    p.add_argument("--order", choices=("pixel", "pass"), default="pass",
                   help="record order: all samples of a pixel together, or "
                        "pass after pass (default; sweep --equal-time needs it)")
    p.add_argument("--size", type=parse_size, help="film size WxH, overriding the scene's")
    p.add_argument("--variant", default="llvm_ad_rgb",
                   help="Mitsuba variant: llvm_ad_rgb (default, needs libLLVM >= 16) "
                        "or scalar_rgb (no LLVM, slow: for small films)")
    p.add_argument("--threads", type=positive, help="worker threads (default: all cores)")
    p.add_argument("--reference-spp", type=positive, help="samples per pixel of the reference")
    p.add_argument("--reference-out", help="the reference EXR to write")
    p.add_argument("--albedo-out", help="write the first-hit albedo (Mitsuba's aov integrator) "
                   "to this EXR: OIDN's auxiliary input (pathdensity filter --albedo)")
    p.add_argument("--normal-out", help="write the shading normal to this EXR "
                   "(pathdensity filter --normal)")
    p.add_argument("--aux-spp", type=positive, default=16,
                   help="samples per pixel of the albedo and normal (default 16)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    args = p.parse_args(argv)
    if (args.reference_spp is None) != (args.reference_out is None):
        p.error("--reference-spp and --reference-out go together")
    if args.seed < 0 or args.seed >= 1 << 32:
        p.error(f"--seed must be in 0..2^32-1, got {args.seed}")
    return args


def load_mitsuba(variant, threads):
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError as e:
        raise ExportError(f"cannot import mitsuba ({e}); run tools/mitsuba/setup.sh "
                          "and use tools/mitsuba/.venv/bin/python")
    if not variant.endswith("_rgb"):
        raise ExportError(f"variant {variant!r}: the dump holds RGB, use an *_rgb variant")
    try:
        mi.set_variant(variant)
    except Exception as e:  # drjit raises several types here, e.g. without libLLVM
        raise ExportError(f"Mitsuba variant {variant!r} is unavailable: {first_line(e)}"
                          + (" (llvm variants need libLLVM >= 16, e.g. Debian's libllvm19)"
                             if variant.startswith("llvm") else ""))
    if threads is not None:
        dr.set_thread_count(threads)
    return mi, dr


def first_line(error):
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


def load_scene(mi, path, size):
    """Loads the scene, with the film's size replaced when `size` is given."""
    if not os.path.isfile(path):
        raise ExportError(f"{path}: no such file")
    try:
        tree = ET.parse(path)
    except ET.ParseError as e:
        raise ExportError(f"{path}: not a Mitsuba scene (not XML: {e})")
    root = tree.getroot()
    if root.tag != "scene":
        raise ExportError(f"{path}: not a Mitsuba scene (the root element is <{root.tag}>, "
                          "not <scene>)")
    if size is not None:
        films = root.findall(".//sensor/film")
        if len(films) != 1:
            raise ExportError(f"{path}: --size needs exactly one <film> inside a <sensor>, "
                              f"found {len(films)}")
        for name, value in zip(("width", "height"), size):
            for old in films[0].findall(f"integer[@name='{name}']"):
                films[0].remove(old)
            ET.SubElement(films[0], "integer", name=name, value=str(value))
    resolver = mi.file_resolver()
    resolver.prepend(os.path.dirname(os.path.abspath(path)))
    try:
        return mi.load_string(ET.tostring(root, encoding="unicode"))
    except Exception as e:
        raise ExportError(f"{path}: Mitsuba cannot load it: {first_line(e)}")


def check_scene(mi, path, scene):
    sensors = scene.sensors()
    if not sensors:
        raise ExportError(f"{path}: the scene has no sensor")
    sensor = sensors[0]
    film = sensor.film()
    if film.class_name() != "HDRFilm":
        raise ExportError(f"{path}: the film is {film.class_name()}; the exporter needs hdrfilm")
    integrator = scene.integrator()
    kind = {"PathIntegrator": "path", "VolumetricPathIntegrator": "volpath"}.get(
        integrator.class_name())
    if kind not in SUPPORTED_INTEGRATORS:
        raise ExportError(f"{path}: the integrator is {integrator.class_name()}; the exporter "
                          f"supports {' and '.join(SUPPORTED_INTEGRATORS)}")
    return sensor, film, integrator


def chunk_seed(seed, stream, chunk):
    """A 32-bit seed for one chunk; Mitsuba scrambles (seed, lane) with TEA."""
    z = (seed * 0x9E3779B97F4A7C15 + stream * 0xBF58476D1CE4E5B9 + chunk + 1) & (2**64 - 1)
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & (2**64 - 1)
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & (2**64 - 1)
    return (z ^ (z >> 31)) & 0xFFFFFFFF


class Camera:
    """Mitsuba's render_sample, one chunk of passes at a time."""

    def __init__(self, mi, dr, scene, sensor, film, integrator):
        self.mi, self.dr = mi, dr
        self.scene, self.sensor, self.integrator = scene, sensor, integrator
        self.width, self.height = (int(v) for v in film.crop_size())
        self.crop = np.array([int(v) for v in film.crop_offset()], dtype=np.float64)
        full = np.array([int(v) for v in film.size()], dtype=np.float64)
        self.scale = 1.0 / full
        self.sampler = mi.load_dict({"type": "independent"})
        self.scalar = not dr.is_array_v(mi.Float)
        self.spp = 1

    def passes_per_chunk(self, spp):
        return max(1, min(spp, SAMPLES_PER_CHUNK // (self.width * self.height)))

    def chunk(self, seed, stream, index, passes):
        """Records (x, y, t, r, g, b) of `passes` passes, pass-major, as float32."""
        pixels = self.width * self.height
        n = pixels * passes
        s = chunk_seed(seed, stream, index)
        if self.scalar:
            return np.stack([self._scalar_sample(s, i, i % pixels) for i in range(n)])
        mi, dr = self.mi, self.dr
        self.sampler.seed(s, n)
        lane = dr.arange(mi.UInt32, n)
        pixel = lane % pixels
        px = mi.Float(pixel % self.width)
        py = mi.Float(pixel // self.width)
        offset = self.sampler.next_2d()
        out_x, out_y, t, value = self._trace(px + offset.x, py + offset.y)
        t = np.broadcast_to(np.asarray(t, dtype=np.float32), (n,))
        return np.column_stack([np.asarray(out_x, dtype=np.float32),
                                np.asarray(out_y, dtype=np.float32), t]
                               + [np.asarray(value[c], dtype=np.float32) for c in range(3)])

    def _scalar_sample(self, s, lane, pixel):
        # The scalar sampler has one stream: seed it per sample.
        self.sampler.seed((s + lane * 0x9E3779B9) & 0xFFFFFFFF)
        u = self.sampler.next_2d()
        x, y, t, value = self._trace(pixel % self.width + u[0], pixel // self.width + u[1])
        return np.array([x, y, t, value[0], value[1], value[2]], dtype=np.float32)

    def _trace(self, x, y):
        """One camera sample at film position (x, y) of the crop window."""
        mi, dr, sensor = self.mi, self.dr, self.sensor
        sampler = self.sampler
        open_time = sensor.shutter_open_time()
        u_time = sampler.next_1d() if open_time > 0 else 0.0
        time_ = sensor.shutter_open() + u_time * open_time
        wavelength = sampler.next_1d()
        aperture = sampler.next_2d() if sensor.needs_aperture_sample() else mi.Point2f(0.5)
        position = mi.Point2f((x + self.crop[0]) * self.scale[0],
                              (y + self.crop[1]) * self.scale[1])
        ray, weight = sensor.sample_ray_differential(time_, wavelength, position, aperture)
        # As Mitsuba does: ray differentials narrowed by the sample count.
        ray.scale_differential(max(self.spp ** -0.5, 0.125))
        value, _, _ = self.integrator.sample(self.scene, sampler, ray, None, True)
        value = weight * value
        if not self.scalar:
            dr.eval(x, y, value)
        return x, y, u_time, value


def floor_into_pixel(records, width, height, passes):
    """float32 rounding can lift i + u (u < 1) to i + 1: keep each sample in its pixel."""
    pixels = width * height
    pixel = np.tile(np.arange(pixels, dtype=np.int64), passes)
    for axis, index in ((0, pixel % width), (1, pixel // width)):
        top = np.nextafter((index + 1).astype(np.float32), np.float32(0))
        records[:, axis] = np.minimum(records[:, axis], top)


def passes(camera, spp):
    per = camera.passes_per_chunk(spp)
    for index, first in enumerate(range(0, spp, per)):
        yield index, first, min(per, spp - first)


def export_dump(camera, args, scene_name):
    w, h = camera.width, camera.height
    pixels = w * h
    camera.spp = args.spp
    progress = Progress("export", pixels * args.spp, args.quiet)
    with pds.Presized(args.out, pixels * args.spp, w, h, frames=1, spp=args.spp,
                      order=args.order, scene=scene_name, seed=args.seed,
                      producer=f"tools/mitsuba/export.py ({camera.mi.__version__}, "
                               f"{camera.mi.variant()})") as out:
        for index, first, count in passes(camera, args.spp):
            records = camera.chunk(args.seed, DUMP_STREAM, index, count)
            floor_into_pixel(records, w, h, count)
            if args.order == "pass":
                out[first * pixels:(first + count) * pixels] = records
            else:
                lane = np.arange(pixels * count, dtype=np.int64)
                out[(lane % pixels) * args.spp + first + lane // pixels] = records
            progress.advance(pixels * count)


def export_reference(camera, args):
    w, h = camera.width, camera.height
    pixels = w * h
    total = np.zeros((pixels, 3), dtype=np.float64)
    camera.spp = args.reference_spp
    progress = Progress("reference", pixels * args.reference_spp, args.quiet)
    for index, _, count in passes(camera, args.reference_spp):
        records = camera.chunk(args.seed, REFERENCE_STREAM, index, count)
        total += records[:, 3:6].astype(np.float64).reshape(count, pixels, 3).sum(axis=0)
        progress.advance(pixels * count)
    mean = (total / args.reference_spp).astype(np.float32).reshape(h, w, 3)
    exrio.write_rgb(args.reference_out, mean)


def export_aux(mi, scene, args):
    """The albedo and normal OIDN takes beside the colour: Mitsuba's aov
    integrator on the same film (so the same pixels), at --aux-spp."""
    integrator = mi.load_dict({"type": "aov", "aovs": "albedo:albedo,nn:sh_normal"})
    try:
        image = np.array(mi.render(scene, integrator=integrator, spp=args.aux_spp,
                                   seed=args.seed))
    except Exception as e:
        raise ExportError(f"{args.scene}: the aov integrator failed: {first_line(e)}")
    if image.ndim != 3 or image.shape[2] < 6:
        raise ExportError(f"{args.scene}: the aov integrator gave {image.shape}, not H x W x 6")
    for path, channels in ((args.albedo_out, image[:, :, 0:3]), (args.normal_out, image[:, :, 3:6])):
        if path:
            exrio.write_rgb(path, channels)


def main(argv):
    args = arguments(argv)
    try:
        # Before Mitsuba loads anything: a refusal costs nothing.
        check_outputs([args.scene], [(args.out, "dump"), (args.reference_out, "exr"),
                                     (args.albedo_out, "exr"), (args.normal_out, "exr")])
        mi, dr = load_mitsuba(args.variant, args.threads)
        scene = load_scene(mi, args.scene, args.size)
        sensor, film, integrator = check_scene(mi, args.scene, scene)
        camera = Camera(mi, dr, scene, sensor, film, integrator)
        name = os.path.splitext(os.path.basename(args.scene))[0]
        start = time.monotonic()
        export_dump(camera, args, name)
        seconds = time.monotonic() - start
        if not args.quiet:
            n = camera.width * camera.height * args.spp
            print(f"{args.out}: {n} samples, {camera.width}x{camera.height} at {args.spp} spp "
                  f"in {seconds:.2f} s ({mi.variant()})", file=sys.stderr)
        if args.reference_out:
            export_reference(camera, args)
        if args.albedo_out or args.normal_out:
            export_aux(mi, scene, args)
    except ExportError as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"{PROG}: {e.filename or args.out}: {e.strerror or e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
