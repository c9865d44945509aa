#!/usr/bin/env python3
"""Random rooms of the kind of ../shared/scenes/room-a ... room-d, for judging irfarm on scenes it
has never seen (its defaults were chosen on the shared scenes only).

A room is a box W x H x D (x in [0, W], y up, z in [0, D]) of one-sided diffuse walls facing
inwards, each its own colour; 1-4 diffuse boxes on the floor (Mitsuba's `cube`, rotated about y);
1-3 rectangular area lamps just under the ceiling facing down; with probability 0.6 a window
opening in the far wall (z = D) with a directional sun shining in through it and a constant sky.
The camera stands near the z = 0 wall at eye height and looks into the room. Only the scene
subset of ../shared/scenes/README.md, so Mitsuba 3 reads the same file.

  python3 bench/make_room.py SEED OUT_DIR [--window yes|no] [--lamps rect|mesh|bulb|none]
      [--finish matte|glossy] [--sky constant|envmap|sun-envmap] [--glass]
      writes OUT_DIR/scene.xml (--lamps mesh: ceiling disks and fluorescent tubes, emissive
      triangle meshes, instead of rectangles; --lamps bulb: small spheres, spot and point
      lights; --lamps none: the same room with no lamp, lit by day through its window;
      --finish glossy: a rough plastic floor and a rough metal box; --sky envmap: the
      window lets in an environment map, a photographed sky turned about the vertical at random,
      instead of a sun and a constant sky, as in a real interior such as living-room; it is
      copied to OUT_DIR/sky.exr; --sky sun-envmap: the sun and the constant sky drawn into an
      environment map, OUT_DIR/sky.hdr, as a photographed sky with its sun would light it;
      --glass: a thin glass pane in the window and a glass diffuser under each rectangular lamp)
  python3 bench/make_room.py SEED OUT_DIR --reference 1024      and a Mitsuba 3 reference:
      reference.exr (mean of 256-spp chunks, seeds 1000...), reference.json (seconds, spp and the
      reference's own noise: relmse_half_vs_half of the even and odd chunks and
      relmse_est_ref_vs_truth = half_vs_half / 4, as the shared references have it). Needs
      `pip install mitsuba` and, for llvm_ad_rgb, DRJIT_LIBLLVM_PATH (Debian's libllvm19).

bench/time_vs_error.py --scenes-dir takes a folder of such rooms (with --mitsuba-live: they
have no mitsuba-curve.json).
"""
import argparse
import json
import math
import os
import random
import shutil
import time


def rect(name, mat, scale, rotate, translate, emitter=None):
    """A rectangle ([-1, 1]^2 in xy, normal +z) scaled, rotated (axis, degrees), translated."""
    rot = "".join(f'<rotate {ax}="1" angle="{ang:.4f}"/>' for ax, ang in rotate)
    em = (f'\n        <emitter type="area"><rgb name="radiance" value="{emitter}"/></emitter>'
          if emitter else "")
    return f"""    <shape type="rectangle" id="{name}">
        <transform name="to_world"><scale x="{scale[0]:.5f}" y="{scale[1]:.5f}"/>{rot}<translate x="{translate[0]:.5f}" y="{translate[1]:.5f}" z="{translate[2]:.5f}"/></transform>
        <ref id="{mat}"/>{em}
    </shape>
"""


def rgb(v):
    return ", ".join(f"{c:.4f}" for c in v)


# The environment map of --sky envmap: a real photographed sky (bench/data/README.md; mean
# radiance 8.3), scaled to the brightness of the constant skies and suns above (4x that where the
# room has no lamp: it is all the light there is).
SKY_FILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "sky-19-256x128.exr")
SKY_SCALE = 0.06


def sun_sky_hdr(sun_dir, sun, sky, width=512, height=256, radius_deg=1.5):
    """A latitude-longitude environment map (Mitsuba's: u = phi / 2 pi with phi = atan2(x, -z),
    v = theta / pi from +y) of the constant sky `sky` plus a disc of `radius_deg` around the
    direction the sun comes from (-sun_dir) whose texels' radiance sums to the sun's irradiance
    `sun`, as a Radiance .hdr file (RGBE, run-length scanlines without runs): a photographed
    sky with its sun, in the standard library only."""
    to_sun = [-c for c in sun_dir]
    cos_r = math.cos(math.radians(radius_deg))
    disc, omega = [], 0.0
    for y in range(height):
        theta = (y + 0.5) / height * math.pi
        texel = (2 * math.pi / width) * (math.pi / height) * math.sin(theta)
        for x in range(width):
            phi = (x + 0.5) / width * 2 * math.pi
            d = (math.sin(theta) * math.sin(phi), math.cos(theta), -math.sin(theta) * math.cos(phi))
            if sum(a * b for a, b in zip(d, to_sun)) >= cos_r:
                disc.append(y * width + x)
                omega += texel
    pixels = [list(sky) for _ in range(width * height)]
    for i in disc:
        pixels[i] = [s + e / omega for s, e in zip(sky, sun)]

    def rgbe(c):
        v = max(c)
        if v < 1e-32:
            return (0, 0, 0, 0)
        m, e = math.frexp(v)
        scale = m * 256.0 / v
        return tuple(min(255, int(ch * scale)) for ch in c) + (e + 128,)

    out = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n")
    out += f"-Y {height} +X {width}\n".encode()
    for y in range(height):
        row = [rgbe(pixels[y * width + x]) for x in range(width)]
        out += bytes((2, 2, width >> 8, width & 255))
        for ch in range(4):
            values = [p[ch] for p in row]
            for k in range(0, width, 128):
                chunk = values[k:k + 128]
                out.append(len(chunk))
                out += bytes(chunk)
    return bytes(out)


def make_room(seed, window=None, lamps_kind="rect", finish="matte", sky_kind="constant",
              files=None, glass=False):
    """The scene's XML; files (a dict), when given, receives the other files it names."""
    daylight_only = lamps_kind == "none"
    if daylight_only:
        lamps_kind = "rect"
    rnd = random.Random(seed)
    W, H, D = rnd.uniform(3.5, 7.0), rnd.uniform(2.5, 3.3), rnd.uniform(3.0, 5.5)
    if window is None:
        window = rnd.random() < 0.6
    out = []
    mats = {}

    def mat(name, colour):
        mats[name] = colour

    def wall_colour():
        base = rnd.uniform(0.35, 0.7)
        return [min(0.85, max(0.05, base + rnd.uniform(-0.2, 0.2))) for _ in range(3)]

    mat("mat-floor", [rnd.uniform(0.3, 0.6)] * 3)
    mat("mat-ceiling", [rnd.uniform(0.6, 0.8)] * 3)
    for w in ("z0", "zD", "x0", "xW"):
        mat(f"mat-wall-{w}", wall_colour())
    mat("mat-lamp", [0, 0, 0])
    # Floor (normal +y), ceiling (-y), walls facing inwards.
    out.append(rect("floor", "mat-floor", (W / 2, D / 2), [("x", -90)], (W / 2, 0, D / 2)))
    out.append(rect("ceiling", "mat-ceiling", (W / 2, D / 2), [("x", 90)], (W / 2, H, D / 2)))
    out.append(rect("wall-z0", "mat-wall-z0", (W / 2, H / 2), [], (W / 2, H / 2, 0)))
    out.append(rect("wall-x0", "mat-wall-x0", (D / 2, H / 2), [("y", 90)], (0, H / 2, D / 2)))
    out.append(rect("wall-xW", "mat-wall-xW", (D / 2, H / 2), [("y", -90)], (W, H / 2, D / 2)))
    emitters = []
    if window:
        ww, wh = rnd.uniform(0.9, min(2.2, W - 1.0)), rnd.uniform(0.9, min(1.5, H - 1.2))
        x0 = rnd.uniform(0.4, W - ww - 0.4)
        y0 = rnd.uniform(0.7, H - wh - 0.3)
        x1, y1 = x0 + ww, y0 + wh
        if glass:  # glazed: a thin pane of glass in the opening
            out.append(rect("window-pane", "mat-glass", (ww / 2, wh / 2), [("y", 180)],
                            ((x0 + x1) / 2, (y0 + y1) / 2, D)))
        # The far wall (z = D, normal -z) around the opening: below, above, left, right.
        for k, (a, b, c, d) in enumerate(
                [(0, W, 0, y0), (0, W, y1, H), (0, x0, y0, y1), (x1, W, y0, y1)]):
            out.append(rect(f"wall-zD-{k}", "mat-wall-zD", ((b - a) / 2, (d - c) / 2), [("y", 180)],
                            ((a + b) / 2, (c + d) / 2, D)))
        # The sun comes in through the opening (direction -z, downwards).
        elev = math.radians(rnd.uniform(20, 50))
        az = math.radians(rnd.uniform(-30, 30))
        sun_dir = (math.cos(elev) * math.sin(az), -math.sin(elev), -math.cos(elev) * math.cos(az))
        sun = [rnd.uniform(8, 12) * c for c in (1.0, 0.93, 0.8)]
        emitters.append(f"""    <emitter type="directional">
        <vector name="direction" value="{rgb(sun_dir)}"/>
        <rgb name="irradiance" value="{rgb(sun)}"/>
    </emitter>
""")
        sky = rnd.uniform(0.15, 0.35)
        if sky_kind == "envmap":
            # In place of the sun and the sky (both drawn above, so the rest of the room is the
            # same as with --sky constant).
            emitters = [f"""    <emitter type="envmap">
        <transform name="to_world"><rotate y="1" angle="{rnd.uniform(0, 360):.2f}"/></transform>
        <string name="filename" value="sky.exr"/>
        <float name="scale" value="{SKY_SCALE * sky / 0.25 * (4 if daylight_only else 1):.4f}"/>
    </emitter>
"""]
        elif sky_kind == "sun-envmap":
            # The same sun and sky, drawn into an environment map (a 1.5-degree sun disc).
            emitters = ["""    <emitter type="envmap">
        <string name="filename" value="sky.hdr"/>
    </emitter>
"""]
            if files is not None:
                files["sky.hdr"] = sun_sky_hdr(sun_dir, sun, [sky * 0.8, sky * 0.95, sky * 1.1])
        else:
            emitters.append(f"""    <emitter type="constant">
        <rgb name="radiance" value="{rgb([sky * 0.8, sky * 0.95, sky * 1.1])}"/>
    </emitter>
""")
    else:
        out.append(rect("wall-zD", "mat-wall-zD", (W / 2, H / 2), [("y", 180)], (W / 2, H / 2, D)))
    # Boxes on the floor, in the far part of the room (the camera is by the z = 0 wall).
    boxes = []
    for i in range(rnd.randint(1, 4)):
        sx, sy, sz = rnd.uniform(0.2, 0.7), rnd.uniform(0.2, 0.8), rnd.uniform(0.2, 0.6)
        x, z = rnd.uniform(0.8, W - 0.8), rnd.uniform(max(1.5, 0.45 * D), D - 0.7)
        mat(f"mat-box{i}", [rnd.uniform(0.1, 0.7) for _ in range(3)])
        boxes.append(f"""    <shape type="cube" id="box{i}">
        <transform name="to_world"><scale x="{sx:.4f}" y="{sy:.4f}" z="{sz:.4f}"/><rotate y="1" angle="{rnd.uniform(0, 90):.3f}"/><translate x="{x:.4f}" y="{sy:.4f}" z="{z:.4f}"/></transform>
        <ref id="mat-box{i}"/>
    </shape>
""")
    # Lamps under the ceiling, facing down (rectangles); with lamps="mesh", lamps whose emitting
    # shape is a triangle mesh: a ceiling disk, a fluorescent tube hung under the ceiling, or an
    # upright tube standing by a wall (a cylinder emits from its whole side).
    lamps = []
    covers = []  # glass=True: a thin glass diffuser pane under each rectangular lamp
    cover_boxes = []  # their x, z extents
    for i in range(rnd.randint(1, 3)):
        lw, ld = rnd.uniform(0.15, 0.6), rnd.uniform(0.15, 0.6)
        x, z = rnd.uniform(lw + 0.3, W - lw - 0.3), rnd.uniform(ld + 0.3, D - ld - 0.3)
        power = rnd.uniform(20, 50) * (0.3 / math.sqrt(lw * ld)) ** 0.5
        colour = rgb([power, power * 0.92, power * 0.78])
        if lamps_kind == "bulb":
            lamps.append(bulb(rnd, i, x, H, z, 4 * lw * ld * power))
            continue
        if lamps_kind != "mesh":
            if glass:
                # Lamps may overlap (coplanar emitters, which z-fight); under glass, where only
                # paths through the diffuser find them, Mitsuba and irfarm then see different
                # ones (room 931: 10% apart), so a lamp whose diffuser would overlap an earlier
                # one is left out (its draws are made all the same: the room stays the same).
                box = (x - 1.25 * lw, x + 1.25 * lw, z - 1.25 * ld, z + 1.25 * ld)
                if any(box[0] < b[1] and b[0] < box[1] and box[2] < b[3] and b[2] < box[3]
                       for b in cover_boxes):
                    continue
                cover_boxes.append(box)
                covers.append(rect(f"cover{i}", "mat-glass", (1.25 * lw, 1.25 * ld), [("x", 90)],
                                   (x, H - 0.07, z)))
            lamps.append(rect(f"light{i}", "mat-lamp", (lw, ld), [("x", 90)], (x, H - 0.01, z),
                              emitter=colour))
            continue
        kind = rnd.choice(["disk", "tube", "upright"])
        em = f'<emitter type="area"><rgb name="radiance" value="{{}}"/></emitter>'
        if kind == "disk":
            r = math.sqrt(lw * ld)  # about the rectangle's area
            lamps.append(f"""    <shape type="disk" id="light{i}">
        <transform name="to_world"><scale value="{r:.4f}"/><rotate x="1" angle="90"/><translate x="{x:.4f}" y="{H - 0.01:.4f}" z="{z:.4f}"/></transform>
        <ref id="mat-lamp"/>{em.format(colour)}
    </shape>
""")
            continue
        radius, length = rnd.uniform(0.02, 0.05), rnd.uniform(0.6, min(1.5, W - 1.0))
        # The same power as the rectangle would have: its area 4 lw ld against the tube's
        # 2 pi r l (emitting all round, so about a third of it goes down).
        tube = [c * (4 * lw * ld) / (2 * math.pi * radius * length) * 2.5
                for c in (power, power * 0.92, power * 0.78)]
        if kind == "tube":
            y = H - rnd.uniform(0.1, 0.3)
            x0 = rnd.uniform(0.5, W - 0.5 - length)
            p0, p1 = (x0, y, z), (x0 + length, y, z)
        else:
            wall_x = rnd.choice([0.15 + radius, W - 0.15 - radius])
            y0 = rnd.uniform(0.2, 0.6)
            length = min(length, H - y0 - 0.3)
            p0, p1 = (wall_x, y0, z), (wall_x, y0 + length, z)
        lamps.append(f"""    <shape type="cylinder" id="light{i}">
        <point name="p0" value="{rgb(p0)}"/><point name="p1" value="{rgb(p1)}"/><float name="radius" value="{radius:.4f}"/>
        <ref id="mat-lamp"/>{em.format(rgb(tube))}
    </shape>
""")
    if daylight_only:  # the same room, its lamps drawn (so the rest stays the same) and left out
        lamps = []
        covers = []
    eye = (rnd.uniform(0.3 * W, 0.7 * W), rnd.uniform(1.2, 1.6), rnd.uniform(0.25, 0.5))
    target = (rnd.uniform(0.2 * W, 0.8 * W), rnd.uniform(0.8, 1.4), D * 0.8)
    head = f"""<?xml version="1.0" encoding="utf-8"?>
<!-- bench/make_room.py seed {seed}: {W:.3f} x {H:.3f} x {D:.3f} m, {({'envmap': 'window, environment map', 'sun-envmap': 'window, sun and sky in an environment map'}.get(sky_kind, 'window, sun and sky')) if window else 'no window'}, {len(lamps)} lamp(s), {len(boxes)} box(es) -->
<scene version="3.0.0">
    <default name="spp" value="256"/>
    <default name="resx" value="320"/>
    <default name="resy" value="240"/>
    <default name="max_depth" value="-1"/>
    <integrator type="path"><integer name="max_depth" value="$max_depth"/></integrator>
    <sensor type="perspective">
        <string name="fov_axis" value="x"/>
        <float name="fov" value="{rnd.uniform(65, 78):.2f}"/>
        <transform name="to_world"><lookat origin="{rgb(eye)}" target="{rgb(target)}" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="$resx"/>
            <integer name="height" value="$resy"/>
            <rfilter type="box"/>
        </film>
    </sensor>
"""
    bsdfs = "".join(f"""    <bsdf type="diffuse" id="{n}"><rgb name="reflectance" value="{rgb(c)}"/></bsdf>
""" for n, c in mats.items() if not (finish == "glossy" and n in ("mat-floor", "mat-box0")))
    if finish == "glossy":
        # A varnished floor and a metal first box, as in real interiors (issue 7's materials).
        bsdfs += f"""    <bsdf type="roughplastic" id="mat-floor">
        <rgb name="diffuse_reflectance" value="{rgb(mats["mat-floor"])}"/>
        <float name="alpha" value="{rnd.uniform(0.05, 0.3):.3f}"/>
    </bsdf>
    <bsdf type="roughconductor" id="mat-box0">
        <string name="material" value="{rnd.choice(["Al", "Cu", "Au"])}"/>
        <float name="alpha" value="{rnd.uniform(0.1, 0.35):.3f}"/>
    </bsdf>
"""
    if glass:
        bsdfs += """    <bsdf type="thindielectric" id="mat-glass"/>
"""
    return head + bsdfs + "".join(out) + "".join(emitters) + "".join(boxes) + "".join(lamps) + \
        "".join(covers) + "</scene>\n"


def bulb(rnd, i, x, H, z, flux_scale):
    """A lamp that is not a rectangle: a small sphere hanging under the ceiling, a spot light at
    the ceiling shining down, or a point light; about the flux of the rectangle it replaces
    (flux_scale = its area x radiance, whose flux is pi x that)."""
    kind = rnd.choice(["sphere", "spot", "point"])
    tint = (1.0, 0.92, 0.78)
    y = H - rnd.uniform(0.3, 0.8)
    if kind == "sphere":
        r = rnd.uniform(0.04, 0.1)
        L = [c * flux_scale / (4 * math.pi * r * r) for c in tint]
        return f"""    <shape type="sphere" id="light{i}">
        <point name="center" value="{rgb((x, y, z))}"/><float name="radius" value="{r:.4f}"/>
        <ref id="mat-lamp"/><emitter type="area"><rgb name="radiance" value="{rgb(L)}"/></emitter>
    </shape>
"""
    if kind == "point":
        intensity = [c * flux_scale / 4 for c in tint]
        return f"""    <emitter type="point" id="light{i}">
        <point name="position" value="{rgb((x, y, z))}"/><rgb name="intensity" value="{rgb(intensity)}"/>
    </emitter>
"""
    cutoff = rnd.uniform(25, 50)
    intensity = [c * flux_scale / (2 * (1 - math.cos(math.radians(cutoff)))) for c in tint]
    target = (x + rnd.uniform(-0.5, 0.5), 0, z + rnd.uniform(-0.5, 0.5))
    return f"""    <emitter type="spot" id="light{i}">
        <transform name="to_world"><lookat origin="{rgb((x, H - 0.02, z))}" target="{rgb(target)}"/></transform>
        <rgb name="intensity" value="{rgb(intensity)}"/>
        <float name="cutoff_angle" value="{cutoff:.2f}"/><float name="beam_width" value="{0.75 * cutoff:.2f}"/>
    </emitter>
"""


def make_reference(folder, spp):
    import numpy as np
    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")
    chunk = 256
    n = max(2, spp // chunk)
    scene = mi.load_file(os.path.join(folder, "scene.xml"), spp=chunk)
    t0 = time.time()
    imgs = [np.array(mi.render(scene, spp=chunk, seed=1000 + i), dtype=np.float64)
            for i in range(n)]
    seconds = time.time() - t0
    ref = np.mean(imgs, axis=0)
    even, odd = np.mean(imgs[0::2], axis=0), np.mean(imgs[1::2], axis=0)
    half = float(np.mean((even - odd) ** 2 / (odd ** 2 + 0.01)))
    mi.Bitmap(ref.astype(np.float32)).write(os.path.join(folder, "reference.exr"))
    with open(os.path.join(folder, "reference.json"), "w") as f:
        json.dump({"renderer": "mitsuba " + mi.__version__, "variant": "llvm_ad_rgb",
                   "integrator": "path", "max_depth": -1, "spp": n * chunk,
                   "seconds": round(seconds, 2), "chunks": {"count": n, "spp_each": chunk,
                                                            "seeds": f"1000..{999 + n}"},
                   "relmse_half_vs_half": half, "relmse_est_ref_vs_truth": half / 4}, f, indent=2)
    return seconds, half / 4


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("seed", type=int)
    ap.add_argument("out")
    ap.add_argument("--window", choices=["yes", "no"])
    ap.add_argument("--lamps", choices=["rect", "mesh", "bulb", "none"], default="rect",
                    help="rectangle lamps, lamps of triangle meshes (disks and tubes), bulbs "
                    "(sphere, spot and point lights), or none (lit by day through the window)")
    ap.add_argument("--finish", choices=["matte", "glossy"], default="matte",
                    help="glossy: a rough plastic floor and a rough metal box")
    ap.add_argument("--sky", choices=["constant", "envmap", "sun-envmap"], default="constant",
                    help="envmap: the window lets in a photographed sky (no sun, no constant sky);"
                    " sun-envmap: the sun and the constant sky drawn into an environment map "
                    "(sky.hdr: a 1.5-degree sun disc)")
    ap.add_argument("--glass", action="store_true",
                    help="thin glass (thindielectric): a pane in the window and a diffuser pane "
                    "under each rectangular lamp (a directional sun does not come through the "
                    "pane, in Mitsuba's path tracer or in irfarm: no path reaches a delta light)")
    ap.add_argument("--reference", type=int, default=0, help="spp of a Mitsuba 3 reference")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    window = None if a.window is None else a.window == "yes"
    if a.sky != "constant" or a.lamps == "none":
        if window is False:
            ap.error("--sky envmap and --lamps none light the room through its window: not with "
                     "--window no")
        window = True
    files = {}
    with open(os.path.join(a.out, "scene.xml"), "w") as f:
        f.write(make_room(a.seed, window, a.lamps, a.finish, a.sky, files, a.glass))
    for name, data in files.items():
        with open(os.path.join(a.out, name), "wb") as f:
            f.write(data)
    if a.sky == "envmap":
        shutil.copyfile(SKY_FILE, os.path.join(a.out, "sky.exr"))
    if a.reference > 0:
        seconds, est = make_reference(a.out, a.reference)
        print(f"{a.out}: reference {a.reference} spp in {seconds:.0f} s, "
              f"its own relMSE about {est:.2e}")


if __name__ == "__main__":
    main()
