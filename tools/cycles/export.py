#!/usr/bin/env python3
"""Export Blender Cycles' own camera samples as a pathdensity dump (.pds).

    export.py SCENE -o OUT.pds --spp N [--seed S] [--size WxH] [--order pixel|pass]
              [--route subset|seed] [--positions probe|aov] [--threads T]
              [--reference-spp M --reference-out REF.exr]
              [--albedo-out A.exr] [--normal-out N.exr] [--film-out F.exr]

SCENE is a .blend file or builtin:NAME (tools/cycles/scenes.py: caustic,
highlight, room, textured). Run it with tools/cycles/.venv/bin/python.

The subset route (default) renders sample k of Cycles' own N-sample
sequence, for k = 0 .. N-1, one render each (`use_sample_subset`,
`sample_subset_length = 1`, `sample_offset = k`): every render holds exactly
one sample per pixel, the one Cycles' N-sample render would have added.
The film position of a sample is in no pass: a second render of the same
sample, with the scene hidden from the camera, gives every camera ray's
direction in a vector AOV ("pds_dir", Geometry > Incoming in the world's
shader), which the pinhole camera projects back to the film position the
ray came from (where a sample falls in its pixel does not depend on the
scene). `--positions aov` measures it in the scene's own renders instead,
from the AOV added to every material, as a cross-check. The seed route
renders N times at 1 sample with seed S + k: exact positions (a 1-sample
render's sample sits at the pixel centre) but point-sampled.

Settings that would alter or correlate samples are forced (docs/renderers.md):
a 1-pixel box filter, the tabulated Sobol pattern, no glossy blur, no path
guiding, no denoising, no compositing, no adaptive sampling, no clamping,
the CPU device with a fixed thread count, a fixed (not animated) seed.
"""

import argparse
import contextlib
import os
import shutil
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))
sys.path.insert(0, HERE)
import exrio  # noqa: E402
import pds  # noqa: E402
from exporter import ExportError, Progress, check_outputs, parse_size, positive  # noqa: E402

PROG = "export.py"
AOV = "pds_dir"
# Projected positions this far (in pixels) outside their pixel are float
# rounding and are clamped in (and counted); farther is an error.
EPSILON = 1e-3
# The reference uses seed S + this (mod 2^31), far from the seed route's S + k.
REFERENCE_SEED_OFFSET = 1 << 30
SEED_MAX = 2**31 - 1


def arguments(argv):
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0])
    p.add_argument("scene", help="a .blend file, or builtin:NAME (caustic, highlight, room, textured)")
    p.add_argument("-o", "--out", required=True, help="the dump to write (.pds)")
    p.add_argument("--spp", type=positive, required=True, help="samples per pixel")
    p.add_argument("--seed", type=int, default=0, help="Cycles' seed (default 0)")
    p.add_argument("--size", type=parse_size, help="film size WxH, overriding the scene's")
    p.add_argument("--order", choices=("pixel", "pass"), default="pass",
                   help="record order (default pass: sample k of every pixel, then k + 1)")
    p.add_argument("--route", choices=("subset", "seed"), default="subset",
                   help="subset (default): Cycles' own N-sample sequence, one sample per "
                        "render, positions from a probe render; seed: N 1-sample renders "
                        "with seeds S + k, records at pixel centres")
    p.add_argument("--positions", choices=("probe", "aov"), default="probe",
                   help="subset route: where the film positions come from. probe (default): "
                        "a second render of each sample with the scene hidden from the camera "
                        "(the dump's renders are of the scene as it is); aov: measured from a "
                        "direction AOV added to every material, probing only what no material "
                        "saw (a cross-check)")
    p.add_argument("--threads", type=positive, help="Cycles' threads (default: all cores)")
    p.add_argument("--reference-spp", type=positive, help="samples per pixel of the reference")
    p.add_argument("--reference-out", help="the reference EXR to write (a plain Cycles render, "
                   f"seed S + {REFERENCE_SEED_OFFSET})")
    p.add_argument("--albedo-out", help="write Cycles' Denoising Albedo of an N-sample render "
                   "(pathdensity filter --albedo)")
    p.add_argument("--normal-out", help="write Cycles' Denoising Normal (world space) of an "
                   "N-sample render (pathdensity filter --normal)")
    p.add_argument("--film-out", help="write Cycles' own N-sample render with seed S, to "
                   "check the dump against")
    p.add_argument("--quiet", action="store_true", help="no summary line on stderr")
    args = p.parse_args(argv)
    if (args.reference_spp is None) != (args.reference_out is None):
        p.error("--reference-spp and --reference-out go together")
    if not 0 <= args.seed <= SEED_MAX:
        p.error(f"--seed must be in 0..{SEED_MAX}, got {args.seed}")
    if args.route == "seed" and args.seed + args.spp - 1 > SEED_MAX:
        p.error(f"the seed route uses seeds S..S+N-1, beyond {SEED_MAX}")
    return args


@contextlib.contextmanager
def silenced(log):
    """Blender writes to the process's stdout and stderr (file descriptors, not
    sys.stdout): send them to `log` for the block, keep them for errors."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o600)
    try:
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for f in (fd, *saved):
            os.close(f)


def last_error(log):
    try:
        with open(log, errors="replace") as f:
            lines = [l.strip() for l in f if l.strip()]
    except OSError:
        return "no log"
    errors = [l for l in lines if "error" in l.lower()]
    return (errors or lines or ["no output"])[-1]


# ---------------------------------------------------------------- the scene

def load(args, log):
    try:
        with silenced(log):
            import bpy
    except ImportError as e:
        raise ExportError(f"cannot import bpy ({e}); run tools/cycles/setup.sh and use "
                          "tools/cycles/.venv/bin/python")
    if args.scene.startswith("builtin:"):
        import scenes
        name = args.scene[len("builtin:"):]
        if name not in scenes.NAMES:
            raise ExportError(f"{args.scene}: no such builtin scene (there are "
                              f"{', '.join(scenes.NAMES)})")
        with silenced(log):
            scenes.build(name)
    else:
        name = os.path.splitext(os.path.basename(args.scene))[0]
        if not os.path.isfile(args.scene):
            raise ExportError(f"{args.scene}: no such file")
        with open(args.scene, "rb") as f:
            magic = f.read(7)
        if magic not in (b"BLENDER",) and magic[:2] not in (b"\x1f\x8b", b"\x28\xb5"):
            raise ExportError(f"{args.scene}: not a .blend file")
        try:
            with silenced(log):
                bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.scene),
                                         load_ui=False, use_scripts=False)
        except RuntimeError as e:
            raise ExportError(f"{args.scene}: Blender cannot open it: {str(e).strip().splitlines()[-1]}")
    return bpy, bpy.context.scene, name


def check_camera(scene, args):
    """Refuses what the exporter cannot represent, in one line."""
    cam = scene.camera
    if cam is None:
        raise ExportError(f"{args.scene}: the scene has no camera")
    data = cam.data
    if data.dof.use_dof:
        raise ExportError(f"{args.scene}: the camera has depth of field on; the exporter "
                          "needs a pinhole camera (turn Depth of Field off)")
    if scene.render.use_motion_blur:
        raise ExportError(f"{args.scene}: motion blur is on; the exporter handles stills "
                          "(turn Motion Blur off)")
    if args.route == "subset" and data.type != "PERSP":
        raise ExportError(f"{args.scene}: the camera is {data.type.lower()}; the subset route "
                          "projects through a perspective camera (use --route seed)")
    r = scene.render
    if args.route == "subset" and r.pixel_aspect_x != r.pixel_aspect_y:
        raise ExportError(f"{args.scene}: pixel aspect {r.pixel_aspect_x}:{r.pixel_aspect_y}; "
                          "the exporter needs square pixels")


# Linear Rec.709 from the other linear working spaces Blender 5 offers.
# Rec.2020 and Rec.709 share D65: RGB709 = XYZ_to_709 . 2020_to_XYZ, both
# from the primaries. ACEScg (AP1, ACES white) goes to D65 by Bradford, as
# Blender's OCIO config does (ACES-AP0_to_CIE-XYZ-D65_BFD).
def _npm(xy_r, xy_g, xy_b, xy_w):
    def xyz(xy):
        return np.array([xy[0] / xy[1], 1.0, (1 - xy[0] - xy[1]) / xy[1]])
    p = np.column_stack([xyz(xy_r), xyz(xy_g), xyz(xy_b)])
    return p * np.linalg.solve(p, xyz(xy_w))


def _bradford(src, dst):
    b = np.array([[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367],
                  [0.0389, -0.0685, 1.0296]])
    def xyz(xy):
        return np.array([xy[0] / xy[1], 1.0, (1 - xy[0] - xy[1]) / xy[1]])
    return np.linalg.inv(b) @ np.diag((b @ xyz(dst)) / (b @ xyz(src))) @ b


D65 = (0.3127, 0.3290)
ACES_WHITE = (0.32168, 0.33767)
REC709 = _npm((0.64, 0.33), (0.30, 0.60), (0.15, 0.06), D65)
TO_REC709 = {
    "Linear Rec.709": np.eye(3),
    "Linear Rec.2020": np.linalg.inv(REC709) @ _npm((0.708, 0.292), (0.170, 0.797),
                                                    (0.131, 0.046), D65),
    "ACEScg": np.linalg.inv(REC709) @ _bradford(ACES_WHITE, D65)
              @ _npm((0.713, 0.293), (0.165, 0.830), (0.128, 0.044), ACES_WHITE),
}


def colour_matrix(bpy, scene, args):
    """The 3 x 3 matrix from the file's working space to linear Rec.709."""
    space = bpy.data.colorspace.working_space
    if space not in TO_REC709:
        raise ExportError(f"{args.scene}: working colour space {space!r}; the exporter "
                          f"converts only {', '.join(TO_REC709)} to linear Rec.709")
    return space, TO_REC709[space]


def force_settings(bpy, scene, args):
    r, c = scene.render, scene.cycles
    r.engine = "CYCLES"
    if args.size:
        r.resolution_x, r.resolution_y = args.size
    else:
        r.resolution_x = max(1, r.resolution_x * r.resolution_percentage // 100)
        r.resolution_y = max(1, r.resolution_y * r.resolution_percentage // 100)
    r.resolution_percentage = 100
    r.use_border = False
    r.use_compositing = False
    r.use_sequencer = False
    r.use_multiview = False  # one view: a stereo render writes one EXR per eye
    r.use_persistent_data = True  # keep BVH and shaders between the N renders
    r.threads_mode = "FIXED"
    r.threads = args.threads or os.cpu_count() or 1
    c.device = "CPU"
    c.pixel_filter_type = "BOX"  # a 1-pixel box: Cycles ignores filter_width with BOX
    c.sampling_pattern = "TABULATED_SOBOL"
    c.blur_glossy = 0.0
    c.use_guiding = False
    c.use_denoising = False
    c.use_preview_denoising = False
    c.use_adaptive_sampling = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.use_animated_seed = False
    c.time_limit = 0.0
    for layer in scene.view_layers:
        layer.cycles.use_denoising = False
    # Render only the active view layer.
    active = bpy.context.view_layer
    for layer in scene.view_layers:
        layer.use = layer == active
    im = r.image_settings
    im.media_type = "MULTI_LAYER_IMAGE"
    im.file_format = "OPEN_EXR_MULTILAYER"
    im.color_depth = "32"
    im.exr_codec = "NONE"
    im.color_management = "FOLLOW_SCENE"
    r.use_file_extension = True
    return active


def add_direction_aov(bpy, layer, materials):
    """Registers the vector AOV; with `materials`, Geometry > Incoming feeds it
    in every material: the camera ray's direction (negated) where it ends.
    Never in the world's shader of the renders that make the dump: a
    Geometry node there makes Cycles build an importance map for the world
    light, which changes its sampling, so the values (measured on
    `highlight`: 572 of 1024 pixels of a 1-sample render changed)."""
    if AOV not in [a.name for a in layer.aovs]:
        aov = layer.aovs.add()
        aov.name = AOV
    layer.aovs[AOV].type = "COLOR"
    if not materials:
        return
    for m in bpy.data.materials:
        if m.node_tree is not None:
            _direction_nodes(m.node_tree)


def _direction_nodes(nt):
    geo = nt.nodes.new("ShaderNodeNewGeometry")
    out = nt.nodes.new("ShaderNodeOutputAOV")
    out.aov_name = AOV
    nt.links.new(geo.outputs["Incoming"], out.inputs["Color"])
    return geo, out


# ---------------------------------------------------------------- rendering

class Renderer:
    def __init__(self, bpy, scene, layer, workdir, log):
        self.bpy, self.scene, self.layer = bpy, scene, layer
        self.workdir, self.log = workdir, log
        self.count = 0
        self.seconds = {}  # kind -> (renders, seconds)

    def render(self, samples, seed, offset=None, denoising_data=False, kind="sample"):
        """One Cycles render; returns its passes {name: (h, w, channels)}."""
        c = self.scene.cycles
        c.samples = samples
        c.seed = seed
        c.use_sample_subset = offset is not None
        if offset is not None:
            c.sample_offset = offset
            c.sample_subset_length = 1
        self.layer.cycles.denoising_store_passes = denoising_data
        path = os.path.join(self.workdir, f"render{self.count}.exr")
        self.count += 1
        self.scene.render.filepath = path
        start = time.monotonic()
        try:
            with silenced(self.log):
                self.bpy.ops.render.render(write_still=True, layer=self.layer.name)
        except RuntimeError as e:
            raise ExportError(f"Cycles failed: {str(e).strip().splitlines()[-1]}")
        n, t = self.seconds.get(kind, (0, 0.0))
        self.seconds[kind] = (n + 1, t + time.monotonic() - start)
        if not os.path.exists(path):
            raise ExportError(f"Cycles wrote no image: {last_error(self.log)}")
        channels, (w, h) = exrio.read(path)
        os.remove(path)
        passes = {}
        prefix = self.layer.name + "."
        for name in channels:
            if not name.startswith(prefix):
                continue
            pass_name, _, channel = name[len(prefix):].rpartition(".")
            passes.setdefault(pass_name, {})[channel] = channels[name]
        out = {}
        for pass_name, chans in passes.items():
            order = [k for k in ("R", "G", "B", "X", "Y", "Z", "A") if k in chans] or sorted(chans)
            out[pass_name] = np.stack([chans[k] for k in order], axis=-1)
        return out


class Projection:
    """World direction of a camera ray -> film position in pixels (row 0 at
    the top), through Blender's camera frame (sensor fit, shift, lens)."""

    def __init__(self, scene):
        cam = scene.camera
        frame = [np.array(v, dtype=np.float64) for v in cam.data.view_frame(scene=scene)]
        xs = [v[0] for v in frame]
        ys = [v[1] for v in frame]
        self.left, self.right = min(xs), max(xs)
        self.bottom, self.top = min(ys), max(ys)
        self.z = frame[0][2]
        m = np.array(cam.matrix_world, dtype=np.float64)[:3, :3]
        self.rotation = m / np.linalg.norm(m, axis=0)  # columns: the camera's axes
        self.width = scene.render.resolution_x
        self.height = scene.render.resolution_y

    def __call__(self, direction):
        local = direction.reshape(-1, 3).astype(np.float64) @ self.rotation
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = self.z / local[:, 2]
            x = (local[:, 0] * scale - self.left) / (self.right - self.left) * self.width
            y = (self.top - local[:, 1] * scale) / (self.top - self.bottom) * self.height
        return x, y, scale > 0


class Positions:
    """Checks each projected position against its own pixel."""

    def __init__(self, width, height):
        self.width, self.height = width, height
        px = np.arange(width * height)
        self.ix = (px % width).astype(np.float64)
        self.iy = (px // width).astype(np.float64)
        self.clamped = 0
        self.probed = 0
        self.worst = 0.0

    def place(self, direction, projection, k, counted=slice(None)):
        d = direction.reshape(-1, 3).astype(np.float64)
        length = np.linalg.norm(d, axis=1)
        missing = length == 0.0
        bad = ~missing & (np.abs(length - 1.0) > 1e-4)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ExportError(f"sample {k} of pixel ({int(self.ix[i])}, {int(self.iy[i])}): the "
                              f"direction AOV has length {length[i]:.6f}, not 1 (a material "
                              f"writes {AOV!r} itself, or its colour was converted)")
        x, y, ahead = projection(-d)  # Incoming points back at the camera
        x = np.where(missing, self.ix + 0.5, x)
        y = np.where(missing, self.iy + 0.5, y)
        ahead |= missing
        out = np.zeros(len(d), bool)
        for pos, lo in ((x, self.ix), (y, self.iy)):
            off = np.maximum(lo - pos, pos - (lo + 1.0))  # > 0: outside [lo, lo + 1]
            self.worst = max(self.worst, float(np.max(np.maximum(off, 0.0), initial=0.0)))
            out |= ~ahead | ~(off < EPSILON)
        if out.any():
            i = int(np.flatnonzero(out)[0])
            raise ExportError(f"sample {k} of pixel ({int(self.ix[i])}, {int(self.iy[i])}) projects "
                              f"to ({x[i]:.4f}, {y[i]:.4f}), more than {EPSILON} px outside its "
                              "pixel: the camera is not the pinhole the exporter models")
        fx = np.float32(x)
        fy = np.float32(y)
        lo_x, lo_y = np.float32(self.ix), np.float32(self.iy)
        hi_x = np.nextafter(np.float32(self.ix + 1), np.float32(0))
        hi_y = np.nextafter(np.float32(self.iy + 1), np.float32(0))
        cx = np.clip(fx, lo_x, hi_x)
        cy = np.clip(fy, lo_y, hi_y)
        self.clamped += int(np.count_nonzero(((cx != fx) | (cy != fy))[counted]))
        return cx, cy, missing


def colour(passes, matrix):
    rgb = passes["Combined"][..., :3].reshape(-1, 3).astype(np.float64)
    return (rgb @ matrix.T).astype(np.float32) if matrix is not None else rgb.astype(np.float32)


def export_dump(renderer, args, scene, name, matrix):
    w, h = scene.render.resolution_x, scene.render.resolution_y
    pixels = w * h
    progress = Progress(f"{args.route} renders", args.spp)
    positions = Positions(w, h)
    projection = Projection(scene) if args.route == "subset" else None
    centre_x = (np.arange(pixels) % w + 0.5).astype(np.float32)
    centre_y = (np.arange(pixels) // w + 0.5).astype(np.float32)
    producer = (f"tools/cycles/export.py (Blender {renderer.bpy.app.version_string}, "
                f"{args.route} route)")

    def index(k):
        if args.order == "pass":
            return np.arange(k * pixels, (k + 1) * pixels)
        return np.arange(pixels) * args.spp + k

    unplaced = {}  # sample k -> the pixels whose sample k had no direction
    with pds.Presized(args.out, pixels * args.spp, w, h, frames=1, spp=args.spp,
                      order=args.order, scene=name, seed=args.seed, producer=producer) as out:
        for k in range(args.spp):
            if args.route == "subset":
                passes = renderer.render(args.spp, args.seed, offset=k)
                if args.positions == "aov":
                    if AOV not in passes:
                        raise ExportError(f"Cycles wrote no {AOV!r} pass")
                    x, y, missing = positions.place(passes[AOV][..., :3], projection, k)
                else:
                    x, y, missing = centre_x, centre_y, np.ones(pixels, bool)
                if missing.any():
                    unplaced[k] = np.flatnonzero(missing)
            else:
                passes = renderer.render(1, args.seed + k)
                x, y = centre_x, centre_y
            rgb = colour(passes, matrix)
            out[index(k)] = np.column_stack([x, y, np.zeros(pixels, np.float32), rgb])
            progress.advance()
        if unplaced:
            probe(renderer, args, scene, positions, projection, unplaced, out, index)
    return positions


def probe(renderer, args, scene, positions, projection, unplaced, out, index):
    """Film positions for the samples that have none: all of them with
    `--positions probe`, else those whose camera ray ended where no material
    writes the AOV (the world, a light seen directly, an object without a
    material). Where a sample lands in its pixel depends only on the pixel,
    the seed, N and k (Cycles' PRNG_FILTER dimension), not on the scene, so
    the same samples are rendered again with the camera's clipping range
    shrunk to nothing and every object hidden from the camera: every camera
    ray then reaches the world, whose shader writes the AOV for these
    renders only. Everything is put back afterwards."""
    bpy = renderer.bpy
    cam = scene.camera.data
    made_world = scene.world is None
    if made_world:
        scene.world = bpy.data.worlds.new("pds_probe")
    world = scene.world
    nodes = _direction_nodes(world.node_tree)
    saved = (scene.render.film_transparent, cam.clip_start, cam.clip_end,
             {obj.name: obj.visible_camera for obj in scene.objects})
    scene.render.film_transparent = False
    cam.clip_end = cam.clip_start * (1.0 + 1e-6)
    for obj in scene.objects:
        obj.visible_camera = False
    try:
        probe_renders(renderer, args, positions, projection, unplaced, out, index)
    finally:
        scene.render.film_transparent, cam.clip_start, cam.clip_end = saved[:3]
        for obj in scene.objects:
            obj.visible_camera = saved[3][obj.name]
        for n in nodes:
            world.node_tree.nodes.remove(n)
        if made_world:
            scene.world = None
            bpy.data.worlds.remove(world)


def probe_renders(renderer, args, positions, projection, unplaced, out, index):
    progress = Progress("probe renders", len(unplaced))
    for k, where in unplaced.items():
        passes = renderer.render(args.spp, args.seed, offset=k, kind="probe")
        x, y, missing = positions.place(passes[AOV][..., :3], projection, k, where)
        if missing[where].any():
            raise ExportError(f"sample {k}: the probe render has no direction either")
        records = np.asarray(out.array[index(k)[where]])
        records["x"], records["y"] = x[where], y[where]
        out[index(k)[where]] = records
        progress.advance()
    positions.probed = sum(len(v) for v in unplaced.values())


def image_of(passes, name, matrix, h, w):
    img = passes[name][..., :3].reshape(-1, 3).astype(np.float64)
    if matrix is not None:
        img = img @ matrix.T
    return img.astype(np.float32).reshape(h, w, 3)


def main(argv):
    args = arguments(argv)
    workdir = tempfile.mkdtemp(prefix="pds-cycles-")
    log = os.path.join(workdir, "blender.log")
    try:
        check_outputs([args.scene], [(args.out, "dump")] + [
            (p, "exr") for p in (args.reference_out, args.albedo_out, args.normal_out,
                                 args.film_out)])
        bpy, scene, name = load(args, log)
        check_camera(scene, args)
        space, matrix = colour_matrix(bpy, scene, args)
        layer = force_settings(bpy, scene, args)
        if args.route == "subset":
            add_direction_aov(bpy, layer, materials=args.positions == "aov")
        layer.update()  # matrix_world of objects moved by a script
        renderer = Renderer(bpy, scene, layer, workdir, log)
        w, h = scene.render.resolution_x, scene.render.resolution_y
        identity = matrix if space != "Linear Rec.709" else None
        start = time.monotonic()
        positions = export_dump(renderer, args, scene, name, identity)
        seconds = time.monotonic() - start
        if not args.quiet:
            extra = ""
            if args.route == "subset":
                extra = (f"; {positions.clamped} positions clamped into their pixel (worst "
                         f"{positions.worst:.2e} px out), positions: {positions.probed} from the probe"
                         + (f", {w * h * args.spp - positions.probed} from the materials' AOV"
                            if args.positions == "aov" else ""))
            times = ", ".join(f"{n} {kind} renders, {t / n:.3f} s each"
                              for kind, (n, t) in renderer.seconds.items())
            print(f"{args.out}: {w * h * args.spp} samples, {w}x{h} at {args.spp} spp, "
                  f"{args.route} route in {seconds:.2f} s ({times}), "
                  f"{space}{' -> Linear Rec.709' if identity is not None else ''}{extra}",
                  file=sys.stderr)
        if args.film_out or args.albedo_out or args.normal_out:
            c = scene.cycles
            c.use_sample_subset = False
            passes = renderer.render(args.spp, args.seed, denoising_data=bool(
                args.albedo_out or args.normal_out), kind="film")
            if args.film_out:
                exrio.write_rgb(args.film_out, image_of(passes, "Combined", identity, h, w))
            if args.albedo_out:
                # Albedo is a colour: in the working space, converted like the image.
                exrio.write_rgb(args.albedo_out,
                                image_of(passes, "Denoising Albedo", identity, h, w))
            if args.normal_out:
                exrio.write_rgb(args.normal_out, image_of(passes, "Denoising Normal", None, h, w))
        if args.reference_out:
            scene.cycles.use_sample_subset = False
            seed = (args.seed + REFERENCE_SEED_OFFSET) % (SEED_MAX + 1)
            passes = renderer.render(args.reference_spp, seed, kind="reference")
            exrio.write_rgb(args.reference_out, image_of(passes, "Combined", identity, h, w))
    except ExportError as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"{PROG}: {e.filename or args.out}: {e.strerror or e}", file=sys.stderr)
        return 1
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
