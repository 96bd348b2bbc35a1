"""The Python module against the command line it wraps.

The module's decisions and images must be the `filter` command's byte for
byte on the same dump and configuration; its dumps the format crate's.
Needs the module installed (tools/python/setup.sh) and the release binary
(cargo build --release, or PATHDENSITY_CLI naming it); tests/python_module.rs
runs this file with both.
"""

import gc
import json
import os
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import pathdensity as pd

ROOT = Path(__file__).resolve().parents[3]
CLI = os.environ.get("PATHDENSITY_CLI", str(ROOT / "target/release/pathdensity"))


def cli(*args, ok=True):
    p = subprocess.run([CLI, *map(str, args)], capture_output=True, text=True)
    if ok:
        assert p.returncode == 0, f"{args}: {p.stderr}"
    return p


def synth(path, **kw):
    args = ["synth", "-o", path]
    for k, v in kw.items():
        flag = "--" + k.replace("_", "-")
        args += [flag] if v is True else [flag, v]
    cli(*args)
    return path


def read_exrs(paths, tmp):
    """The f32 pixels of EXRs, exactly: `import images` makes them a dump
    (one record a pixel, at its centre, rgb as stored), read back here."""
    out = tmp / f"exr-{len(list(tmp.glob('exr-*')))}.pds"
    cli("import", "images", *paths, "-o", out)
    h, r = pd.read_dump(out)
    return np.array(r[:, 3:6]).reshape(len(paths), h["height"], h["width"], 3)


def exr_files(out, name, frames):
    if frames == 1:
        return [out / f"{name}.exr"]
    return [out / f"{name}_{f:04}.exr" for f in range(frames)]


def flags(config):
    args = []
    for k, v in config.items():
        if isinstance(v, (list, tuple)):
            v = ",".join(v)
        args += ["--" + k.replace("_", "-"), v]
    return args


def same_bits(a, b):
    a, b = np.asarray(a, np.float32), np.asarray(b, np.float32)
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


CASES = {
    # The defaults (every method this machine makes), a pixel-major still.
    "defaults": (dict(width=40, height=24, spp=16, fireflies=0.01), {}),
    # Options of every kind, a pass-major animation, a list of methods.
    "options": (
        dict(width=24, height=16, spp=12, frames=2, order="pass", fireflies=0.02, seed=7),
        dict(k=6, sigma_color=80.0, recon="gaussian", white="2", final_pass="stored",
             methods=["median", "clamp", "filtered_energy_bilateral_ci", "rwmc"],
             rwmc_kappa=8.0, clamp=5.0),
    ),
    # The paper's joint space and a small light; a comma string of methods.
    "paper": (
        dict(width=32, height=32, spp=16, fireflies=0.005, light="10,10,2,50"),
        dict(k=10, sigma_color=100.0, color_space="cielab", white="1",
             methods="trimmed,median3,filtered_bilateral"),
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_decisions_images_and_report_equal_the_cli(tmp_path, case):
    film, config = CASES[case]
    dump = synth(tmp_path / "d.pds", **film)
    frames = film.get("frames", 1)
    # A reference: the mean of a clean render of the same film at more spp.
    clean = synth(tmp_path / "clean.pds", **{**film, "spp": 64, "fireflies": 0})
    cli("filter", clean, "-o", tmp_path / "clean", "--no-html", "--methods", "median")
    ref_files = []
    for f, src in enumerate(exr_files(tmp_path / "clean", "mean", frames)):
        dst = tmp_path / (f"ref_{f:04}.exr" if frames > 1 else "ref.exr")
        dst.write_bytes(src.read_bytes())
        ref_files.append(dst)
    reference = read_exrs(ref_files, tmp_path)

    out = tmp_path / "out"
    cli("filter", dump, "-o", out, "--decisions", tmp_path / "dec.bin", "--no-html",
        "--sigma-map", "--reference", tmp_path / "ref.exr", *flags(config))
    report = json.loads((out / "report.json").read_text())

    h, records = pd.read_dump(dump)
    kw = dict(config)
    if "white" in kw:
        kw["white"] = float(kw["white"])
    res = pd.filter(records, header=h, reference=reference, sigma_map=True, **kw)

    assert res.decisions.dtype == np.uint8
    assert res.decisions.tobytes() == (tmp_path / "dec.bin").read_bytes()
    exrs = {n.rsplit(".", 1)[0] for n in report["outputs"] if n.endswith(".exr")}
    names = {n.rsplit("_", 1)[0] if frames > 1 else n for n in exrs}
    assert names == set(res.images) | {"rejected", "sigma"}
    for name, image in [*res.images.items(), ("rejected", res.rejected), ("sigma", res.sigma)]:
        assert image.shape == (frames, h["height"], h["width"], 3), name
        assert image.dtype == np.float32, name
        want = read_exrs(exr_files(out, name, frames), tmp_path)
        assert same_bits(image, want), f"{name} differs from the command's EXR"
    assert res.counts == report["counts"]
    assert res.metrics == report["metrics"]
    assert set(res.metrics) == set(res.images)
    assert res.recommended == report["recommended"]
    assert res.denoiser == report.get("denoiser")
    assert res.config == report["config"]
    assert res.white == report["white"]
    assert res.warnings == report["warnings"]
    assert res.fallback_pixels == report["fallback_pixels"]


def test_a_stills_reference_in_either_shape_and_any_thread_count(tmp_path):
    h, r = pd.read_dump(synth(tmp_path / "d.pds", width=20, height=12, spp=8, fireflies=0.02))
    ref = pd.filter(r, header=h, methods="median").images["median"]
    four = pd.filter(r, header=h, methods="median", reference=ref, threads=1)
    three = pd.filter(r, header=h, methods="median", reference=ref[0].astype(np.float64), threads=2)
    assert four.metrics == three.metrics and four.metrics["median"]["rms"] == 0
    assert four.decisions.tobytes() == three.decisions.tobytes()
    assert four.threads == 1 and three.threads == 2


def test_without_a_reference_there_are_no_metrics(tmp_path):
    h, r = pd.read_dump(synth(tmp_path / "d.pds", width=16, height=16, spp=8))
    res = pd.filter(r, width=16, height=16, spp=8, methods="median")
    assert res.metrics == {}
    assert list(res.images) == ["mean", "filtered", "median"]
    # The film given one way or the other, the same run.
    again = pd.filter(r, header=h, methods=["median"])
    assert again.decisions.tobytes() == res.decisions.tobytes()
    assert repr(res).startswith("FilterResult(images=[mean, filtered, median]")
    # By default what a user keeps; "all" every image the machine can make.
    default = pd.filter(r, header=h)
    assert {"mean", "filtered", "filtered_energy"} <= set(default.images)
    assert default.recommended in ("guided", "guided_oidn")
    every = pd.filter(r, header=h, methods="all")
    assert {"median", "rwmc", "statmc", "clamp"} <= set(every.images)
    assert set(default.images) < set(every.images)


@pytest.mark.parametrize("kw", [
    dict(width=32, height=32, spp=16),
    dict(width=20, height=12, spp=9, order="pass"),
    dict(width=16, height=8, spp=4, frames=3, order="pass", pixel_centre=True),
])
def test_read_write_round_trip_byte_for_byte(tmp_path, kw):
    src = synth(tmp_path / "s.pds", **kw)
    h, r = pd.read_dump(src)
    assert h["sample_count"] == r.shape[0] == kw["width"] * kw["height"] * kw["spp"] * kw.get("frames", 1)
    assert h["order"] == kw.get("order", "pixel")
    assert (h["width"], h["height"], h["frames"], h["spp"]) == (
        kw["width"], kw["height"], kw.get("frames", 1), kw["spp"])
    assert h["producer"].startswith("pathdensity synth")
    assert r.dtype == np.float32 and r.shape[1] == 6 and r.flags.c_contiguous
    # Read-only, over the mapped file, which its base keeps mapped.
    assert not r.flags.writeable and not r.flags.owndata
    assert isinstance(r.base, pd.Dump) and Path(r.base.path) == src
    with pytest.raises(ValueError):
        r[0, 0] = 1.0
    data = Path(src).read_bytes()
    assert r.tobytes() == data[len(data) - r.nbytes:]
    out = tmp_path / "copy.pds"
    pd.write_dump(out, r, **h)
    assert out.read_bytes() == data
    # The records outlive every other name of the mapping.
    view = r[5:]
    del h, r
    gc.collect()
    assert view.tobytes() == data[len(data) - view.nbytes:]
    assert isinstance(view.base.base, pd.Dump)
    # Nothing left beside the outputs.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["copy.pds", "s.pds"]
    # The command line reads what the module wrote.
    info = json.loads(cli("info", out, "--json").stdout)
    assert info["header"]["sample_count"] == view.shape[0] + 5


def test_write_dump_from_numpy_and_its_refusals(tmp_path):
    rng = np.random.default_rng(1)
    n = 6 * 4 * 3
    rec = np.zeros((n, 6), np.float32)
    rec[:, 0] = rng.uniform(0, 6, n)
    rec[:, 1] = rng.uniform(0, 4, n)
    rec[:, 3:] = rng.uniform(0, 1, (n, 3))
    p = tmp_path / "n.pds"
    pd.write_dump(p, rec, width=6, height=4, spp=3, scene="mine", seed=9)
    h, back = pd.read_dump(p)
    assert np.array_equal(back, rec)
    assert (h["scene"], h["seed"], h["order"]) == ("mine", 9, "unspecified")
    # The same bytes as the command line's importer of the same array.
    np.save(tmp_path / "n.npy", rec)
    cli("import", "npy", tmp_path / "n.npy", "--width", 6, "--height", 4, "--spp", 3,
        "-o", tmp_path / "i.pds")
    _, imported = pd.read_dump(tmp_path / "i.pds")
    assert imported.tobytes() == back.tobytes()
    # Never replaces a file that is not a dump, and leaves it as it was.
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    with pytest.raises(OSError, match="was not written by pathdensity: refusing to replace it"):
        pd.write_dump(notes, rec, width=6, height=4)
    assert notes.read_text() == "mine"
    with pytest.raises(ValueError, match="sample_count is 3"):
        pd.write_dump(tmp_path / "x.pds", rec, width=6, height=4, sample_count=3)
    with pytest.raises(ValueError, match="every size must be at least 1"):
        pd.write_dump(tmp_path / "x.pds", rec, width=0, height=4)
    with pytest.raises(ValueError, match="unknown order"):
        pd.write_dump(tmp_path / "x.pds", rec, width=6, height=4, order="random")
    with pytest.raises(OSError, match="no/x.pds: cannot create"):
        pd.write_dump(tmp_path / "no" / "x.pds", rec, width=6, height=4)
    assert not (tmp_path / "x.pds").exists()
    assert not [q for q in tmp_path.iterdir() if q.name.startswith(".")]


BAD = [
    (lambda r: r.astype(np.float64), "dtype float32.*got float64"),
    (lambda r: r.astype(">f4"), "dtype float32.*got >f4"),
    (lambda r: np.ascontiguousarray(r[:, :5]), r"shape \(N, 6\).*got \(\d+, 5\)"),
    (lambda r: r.ravel().copy(), r"shape \(N, 6\).*got \(\d+,\)"),
    (lambda r: r.reshape(-1, 2, 6).copy(), r"shape \(N, 6\).*got \(\d+, 2, 6\)"),
    (lambda r: np.asfortranarray(r), "C-contiguous"),
    (lambda r: r[::2], "C-contiguous"),
    (lambda r: np.ascontiguousarray(r.T).T, "C-contiguous"),
    (lambda r: r.tolist(), "numpy array.*got a list"),
]


@pytest.mark.parametrize("bad,message", BAD)
def test_bad_arrays_raise(tmp_path, bad, message):
    _, r = pd.read_dump(synth(tmp_path / "d.pds", width=8, height=8, spp=4))
    arr = bad(np.array(r))
    with pytest.raises(ValueError, match=message):
        pd.filter(arr, width=8, height=8)
    with pytest.raises(ValueError, match=message):
        pd.write_dump(tmp_path / "w.pds", arr, width=8, height=8)
    assert not (tmp_path / "w.pds").exists()


def test_bad_arguments_raise(tmp_path):
    h, r = pd.read_dump(synth(tmp_path / "d.pds", width=8, height=8, spp=4))
    with pytest.raises(ValueError, match="width= and height="):
        pd.filter(r)
    with pytest.raises(TypeError, match="unexpected keyword argument \"kk\".*sigma_color"):
        pd.filter(r, header=h, kk=3)
    with pytest.raises(ValueError, match="invalid value 'tent' for recon: unknown reconstruction filter"):
        pd.filter(r, header=h, recon="tent")
    with pytest.raises(ValueError, match="for methods: unknown method"):
        pd.filter(r, header=h, methods="median,nope")
    with pytest.raises(ValueError, match="for k"):
        pd.filter(r, header=h, k=-1)
    with pytest.raises(ValueError, match=r"reference has shape \(8, 7, 3\).*\(8, 8, 3\)"):
        pd.filter(r, header=h, reference=np.zeros((8, 7, 3), np.float32))
    bad = np.zeros((8, 8, 3))
    bad[1, 2, 0] = np.inf
    with pytest.raises(ValueError, match="reference holds non-finite values"):
        pd.filter(r, header=h, reference=bad)


def one_line(p):
    assert p.returncode != 0
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    return lines[0]


def test_errors_carry_the_command_lines_message(tmp_path):
    dump = synth(tmp_path / "d.pds", width=8, height=8, spp=4)
    h, r = pd.read_dump(dump)
    # A configuration field: the command names it as its flag.
    for flag, value, field in [("--sigma-color", 0, "sigma_color"), ("--alpha", 0.5, "alpha"),
                               ("--rwmc-base", 1, "rwmc_base")]:
        line = one_line(cli("filter", dump, "-o", tmp_path / "o", flag, value, ok=False))
        with pytest.raises(ValueError) as e:
            pd.filter(r, header=h, **{field: value})
        assert line == f"pathdensity: {flag} " + str(e.value)[len(field) + 1:]
        assert str(e.value).startswith(field + " ")
    # A property of the records: the command adds the dump's name.
    outside = np.array(r)
    outside[:, 0] += 100
    pd.write_dump(tmp_path / "out.pds", outside, **h)
    line = one_line(cli("filter", tmp_path / "out.pds", "-o", tmp_path / "o", ok=False))
    with pytest.raises(ValueError) as e:
        pd.filter(outside, header=h)
    assert line == f"pathdensity: {tmp_path / 'out.pds'}: {e.value}"
    assert "no valid sample" in str(e.value)
    # k not below the valid samples.
    line = one_line(cli("filter", dump, "-o", tmp_path / "o", "--k", 1000, ok=False))
    with pytest.raises(ValueError) as e:
        pd.filter(r, header=h, k=1000)
    assert line.endswith(str(e.value)), (line, str(e.value))
    # Files: the same line as the command's, naming the file.
    junk = tmp_path / "junk.pds"
    junk.write_bytes(b"not a dump at all, not at all")
    for path in [junk, tmp_path / "missing.pds", tmp_path]:
        line = one_line(cli("info", path, ok=False))
        with pytest.raises(OSError) as e:
            pd.read_dump(path)
        assert line == f"pathdensity: {e.value}"


def test_albedo_and_normal_are_the_commands_flags(tmp_path):
    """albedo= and normal= are --albedo and --normal: the command's images,
    OIDN's and statmc's guide where OIDN is found, statmc's where it is not
    (PATHDENSITY_EXPECT_OIDN=1 requires OIDN)."""
    dump = synth(tmp_path / "d.pds", width=24, height=16, spp=8, fireflies=0.01)
    h, r = pd.read_dump(dump)
    # Two film-sized EXRs stand for a renderer's albedo and normal.
    aux = synth(tmp_path / "aux.pds", width=24, height=16, spp=4, seed=3)
    cli("filter", aux, "-o", tmp_path / "aux", "--no-html", "--methods", "median")
    a_exr, n_exr = tmp_path / "aux" / "mean.exr", tmp_path / "aux" / "median.exr"
    albedo, normal = (read_exrs([p], tmp_path)[0] for p in (a_exr, n_exr))
    out = tmp_path / "o"
    cli("filter", dump, "-o", out, "--no-html", "--albedo", a_exr, "--normal", n_exr)
    res = pd.filter(r, header=h, albedo=albedo, normal=normal)
    for name, image in res.images.items():
        assert same_bits(image, read_exrs([out / f"{name}.exr"], tmp_path)), name
    oidn = "guided_oidn" in res.images
    if os.environ.get("PATHDENSITY_EXPECT_OIDN") == "1":
        assert oidn, sorted(res.images)
    # The albedo changes the recommended image: OIDN's, or statmc's.
    name = "guided_oidn" if oidn else "guided"
    plain = pd.filter(r, header=h, methods=name)
    assert not same_bits(plain.images[name], res.images[name])
    # aux_prefilter= is --aux-prefilter.
    fast = tmp_path / "fast"
    cli("filter", dump, "-o", fast, "--no-html", "--methods", name, "--albedo", a_exr,
        "--normal", n_exr, "--aux-prefilter", "fast")
    res = pd.filter(r, header=h, methods=name, albedo=albedo, normal=normal, aux_prefilter="fast")
    assert same_bits(res.images[name], read_exrs([fast / f"{name}.exr"], tmp_path))
    with pytest.raises(ValueError, match="expected accurate, fast or none"):
        pd.filter(r, header=h, albedo=albedo, aux_prefilter="clean")
    with pytest.raises(ValueError, match="normal needs albedo"):
        pd.filter(r, header=h, normal=normal)
    with pytest.raises(ValueError, match=r"albedo has shape \(4, 24, 3\)"):
        pd.filter(r, header=h, albedo=albedo[:4])


def test_the_gil_is_released_during_the_filter(tmp_path):
    """Another Python thread keeps counting while filter runs."""
    _, r = pd.read_dump(synth(tmp_path / "d.pds", width=160, height=160, spp=32, fireflies=0.01))
    counts = []
    stop = threading.Event()

    def count():
        n = 0
        while not stop.is_set():
            n += 1
            if n % 1000 == 0:
                counts.append((time.perf_counter(), n))

    t = threading.Thread(target=count)
    t.start()
    try:
        time.sleep(0.05)
        start = time.perf_counter()
        res = pd.filter(r, width=160, height=160, spp=32, threads=1)
        end = time.perf_counter()
    finally:
        stop.set()
        t.join()
    assert res.counts["rejected"] > 0
    inside = [n for (s, n) in counts if start < s < end]
    assert end - start > 0.2, "the filter was too quick to tell"
    # Held, the GIL would let the counter run only at the call's ends.
    assert len(inside) > 10, f"{len(inside)} counts in {end - start:.2f} s"
    spread = [s for (s, _) in counts if start < s < end]
    assert max(spread) - min(spread) > 0.5 * (end - start)
