"""Renders a Lodestar scene (scene format 1) with Mitsuba 3's `path` integrator for a wall
time, for `lodestar compare --peer mitsuba` and scripts/peer-mitsuba.sh (which installs
Mitsuba and runs this). Writes OUT.exr (mean radiance per pixel) and OUT.json.

Only what Mitsuba renders the way Lodestar does is converted; anything else is refused
with a message naming it and exit status 2.
"""

import argparse
import json
import math
import os
import sys
import tempfile
import time

SCENE_KEYS = {"format", "camera", "materials", "shapes", "environment"}
CAMERA_KEYS = {"eye", "target", "up", "fov_y_deg", "width", "height"}
MATERIAL_KEYS = {
    "diffuse": {"type", "albedo", "emission"},
    "conductor": {"type", "specular", "alpha", "emission"},
    "dielectric": {"type", "ior", "emission"},
}
SHAPE_KEYS = {
    "mesh": {"type", "file", "material", "transform"},
    "quad": {"type", "corners", "material"},
    "triangles": {"type", "positions", "indices", "material"},
}


class Unsupported(Exception):
    """A part of the scene the peer cannot render alike."""


def check_keys(where, value, allowed):
    if not isinstance(value, dict):
        raise Unsupported(f"{where}: expected an object")
    extra = sorted(set(value) - allowed)
    if extra:
        raise Unsupported(f"{where}: '{extra[0]}' is not supported by the Mitsuba peer")


def rgb(value):
    return {"type": "rgb", "value": [float(c) for c in value]}


def convert_material(name, material):
    where = f"materials.{name}"
    kind = material.get("type") if isinstance(material, dict) else None
    if kind not in MATERIAL_KEYS:
        raise Unsupported(f"{where}.type: '{kind}' is not supported by the Mitsuba peer")
    check_keys(where, material, MATERIAL_KEYS[kind])
    if kind == "diffuse":
        bsdf = {"type": "diffuse", "reflectance": rgb(material["albedo"])}
    elif kind == "conductor":
        alpha = float(material.get("alpha", 0.0))
        # material 'none' is a perfect reflector (Fresnel 1): the scene format's conductor
        # has no Fresnel term, only the specular colour.
        bsdf = {"type": "conductor", "material": "none", "specular_reflectance": rgb(material["specular"])}
        if alpha > 0.0:
            bsdf.update({"type": "roughconductor", "distribution": "ggx", "alpha": alpha, "sample_visible": True})
    else:
        return {"type": "dielectric", "int_ior": float(material["ior"]), "ext_ior": 1.0}
    # Lodestar reflects alike on both sides.
    return {"type": "twosided", "bsdf": bsdf}


def has_normals(path):
    """Whether an OBJ or PLY file carries vertex normals (Mitsuba would make smooth
    ones where it has none; Lodestar then shades with the flat geometric normal)."""
    with open(path, "rb") as f:
        if path.lower().endswith(".ply"):
            header = b""
            for line in f:
                header += line
                if line.strip() == b"end_header":
                    break
            return b" nx" in header
        return any(line.startswith(b"vn ") for line in f)


def write_obj(path, positions, triangles):
    with open(path, "w") as f:
        for p in positions:
            f.write("v %r %r %r\n" % tuple(float(c) for c in p))
        for t in triangles:
            f.write("f %d %d %d\n" % tuple(i + 1 for i in t))


def convert(scene_path, args, workdir):
    import mitsuba as mi

    if not scene_path.lower().endswith(".json"):
        raise Unsupported("not a scene.json (scene format 1); `lodestar convert` writes one from pbrt-v3 or Mitsuba")
    with open(scene_path) as f:
        scene = json.load(f)
    base = os.path.dirname(os.path.abspath(scene_path))
    check_keys("scene", scene, SCENE_KEYS)
    if scene.get("format") != 1:
        raise Unsupported(f"format: {scene.get('format')!r} is not 1")
    camera = scene["camera"]
    check_keys("camera", camera, CAMERA_KEYS)
    width, height = camera["width"], camera["height"]
    if args.resolution:
        width, height = (int(v) for v in args.resolution.lower().split("x"))
    look_at = mi.ScalarTransform4f().look_at(origin=camera["eye"], target=camera["target"], up=camera["up"])
    result = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": args.max_depth, "rr_depth": args.rr_depth},
        "sensor": {
            "type": "perspective",
            "fov": float(camera["fov_y_deg"]),
            "fov_axis": "y",
            "to_world": look_at,
            "film": {
                "type": "hdrfilm",
                "width": width,
                "height": height,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
            "sampler": {"type": "independent", "sample_count": 1},
        },
    }
    materials = {}
    for name, material in scene["materials"].items():
        materials[name] = (convert_material(name, material), material.get("emission"))
    for i, shape in enumerate(scene["shapes"]):
        where = f"shapes[{i}]"
        kind = shape.get("type") if isinstance(shape, dict) else None
        if kind not in SHAPE_KEYS:
            raise Unsupported(f"{where}.type: '{kind}' is not supported by the Mitsuba peer")
        check_keys(where, shape, SHAPE_KEYS[kind])
        if "material" not in shape:
            raise Unsupported(
                f"{where}: a shape without 'material' takes its OBJ's MTL materials, which the Mitsuba peer "
                "does not read (`lodestar compare --peer mitsuba` writes them inline first)"
            )
        if shape["material"] not in materials:
            raise Unsupported(f"{where}.material: unknown material '{shape['material']}'")
        bsdf, emission = materials[shape["material"]]
        if kind == "mesh":
            path = os.path.join(base, shape["file"])
            plugin = "ply" if path.lower().endswith(".ply") else "obj"
            entry = {"type": plugin, "filename": path, "face_normals": not has_normals(path)}
            if "transform" in shape:
                entry["to_world"] = mi.ScalarTransform4f(shape["transform"])
        else:
            if kind == "quad":
                positions, triangles = shape["corners"], [(0, 1, 2), (0, 2, 3)]
            else:
                indices = shape["indices"]
                positions = shape["positions"]
                triangles = [tuple(indices[j : j + 3]) for j in range(0, len(indices), 3)]
            path = os.path.join(workdir, f"shape{i}.obj")
            write_obj(path, positions, triangles)
            entry = {"type": "obj", "filename": path, "face_normals": True}
        entry["bsdf"] = bsdf
        if emission is not None and max(emission) > 0.0:
            entry["emitter"] = {"type": "area", "radiance": rgb(emission)}
        result[f"shape{i}"] = entry
    environment = scene.get("environment")
    if environment is not None:
        kind = environment.get("type") if isinstance(environment, dict) else None
        if kind != "constant":
            raise Unsupported(f"environment.type: '{kind}' is not supported by the Mitsuba peer")
        check_keys("environment", environment, {"type", "radiance"})
        result["environment"] = {"type": "constant", "radiance": rgb(environment["radiance"])}
    return result, width, height


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("scene")
    parser.add_argument("seconds", type=float)
    parser.add_argument("out")
    parser.add_argument("--max-depth", type=int, default=-1, help="Mitsuba's max_depth (-1: unbounded)")
    parser.add_argument("--rr-depth", type=int, default=5)
    parser.add_argument("--resolution", help="W×H instead of the scene's, e.g. 128x128")
    parser.add_argument("--threads", type=int, help="worker threads (default: all cores)")
    parser.add_argument("--variant", default="llvm_ad_rgb")
    parser.add_argument(
        "--checkpoints",
        default="",
        help="comma-separated seconds: after the first pass to end at or past each, the image so far "
        "is written as OUT-K.exr (K = 1, 2, …) and listed in OUT.json",
    )
    args = parser.parse_args()
    if not args.seconds > 0:
        sys.exit(f"peer-mitsuba: SECONDS must be positive, got {args.seconds}")
    try:
        checkpoint_times = sorted(float(t) for t in args.checkpoints.split(",") if t.strip())
    except ValueError:
        sys.exit(f"peer-mitsuba: --checkpoints must be comma-separated seconds, got {args.checkpoints!r}")

    import drjit as dr
    import mitsuba as mi
    import numpy as np

    mi.set_variant(args.variant)
    if args.threads:
        dr.set_thread_count(args.threads)
    with tempfile.TemporaryDirectory() as workdir:
        try:
            description, width, height = convert(args.scene, args, workdir)
        except Unsupported as error:
            print(f"peer-mitsuba: {args.scene}: {error}", file=sys.stderr)
            sys.exit(2)
        except (KeyError, TypeError, ValueError) as error:
            print(f"peer-mitsuba: {args.scene}: malformed scene ({error!r})", file=sys.stderr)
            sys.exit(2)
        start = time.perf_counter()
        scene = mi.load_dict(description)
        # Passes of equal size after a first one-sample pass (which compiles the kernel and
        # times a sample): each about a second, the last one ending at or just past the budget.
        total = np.zeros((height, width, 3))
        spp, seed, chunk = 0, 0, 1
        stem = os.path.splitext(args.out)[0]
        checkpoints = []
        while True:
            pass_start = time.perf_counter()
            image = mi.render(scene, spp=chunk, seed=seed)
            total += np.array(image, dtype=np.float64)[:, :, :3] * chunk
            spp += chunk
            seed += 1
            now = time.perf_counter()
            while checkpoint_times and now - start >= checkpoint_times[0]:
                checkpoint_times.pop(0)
                if checkpoints and checkpoints[-1]["spp"] == spp:
                    continue
                path = f"{stem}-{len(checkpoints) + 1}.exr"
                mi.Bitmap((total / spp).astype(np.float32), mi.Bitmap.PixelFormat.RGB).write(path)
                checkpoints.append({"seconds": now - start, "spp": spp, "image": path})
            per_sample = (now - pass_start) / chunk
            if seed == 1:
                chunk = max(1, int(1.0 / max(per_sample, 1e-6)))
            left = args.seconds - (now - start)
            if left <= 0:
                break
            # The last pass ends at or just past the budget, as Lodestar's passes do, so
            # the report at SECONDS finds it.
            if left < chunk * per_sample:
                chunk = max(1, math.ceil(left / max(per_sample, 1e-9)))
        seconds = time.perf_counter() - start
        if checkpoints and checkpoints[-1]["spp"] == spp:
            # The last pass reached a checkpoint: OUT.exr is that image.
            os.remove(checkpoints.pop()["image"])
    mean = (total / spp).astype(np.float32)
    mi.Bitmap(mean, mi.Bitmap.PixelFormat.RGB).write(args.out)
    paths = width * height * spp
    report = {
        "peer": f"mitsuba {mi.__version__} {args.variant} path",
        "scene": args.scene,
        "width": width,
        "height": height,
        "spp": spp,
        "seconds": seconds,
        "paths_per_second": paths / seconds,
        "max_depth": args.max_depth,
        "rr_depth": args.rr_depth,
        "checkpoints": checkpoints + [{"seconds": seconds, "spp": spp, "image": args.out}],
    }
    with open(os.path.splitext(args.out)[0] + ".json", "w") as f:
        json.dump(report, f, indent=2)
    print(f"peer-mitsuba: {spp} spp in {seconds:.1f} s, {paths / seconds:.0f} paths/s -> {args.out}")


if __name__ == "__main__":
    main()
