"""Adds Mitsuba 3's own noise at 1/4 size and 64 spp to scenes' reference.json
(mitsuba_quarter_64spp_noise: the relMSE of two Mitsuba renders with seeds 1 and 2, over 2, the
expected relMSE of one render against the truth), as make_reference.py's quarter_noise does, for
scenes whose reference was made without it. The golden-image tests bound irfarm's quarter-size
renders by it: a figure that does not come from irfarm.

    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so \\
        python3 tests/data/scenes/mitsuba_quarter_noise.py cornell-box sunlit-room ...
    ... --same-as cornell-box stress-scale-tiny stress-scale-huge

--same-as SRC: the listed scenes are SRC scaled (their reference is a copy of SRC's); they get
SRC's figure, marked as such (Mitsuba itself fails on stress-scale-tiny).
"""
import argparse, json, os, sys
import numpy as np
import mitsuba as mi

HERE = os.path.dirname(os.path.abspath(__file__))


def relmse(a, b):
    return float(np.mean((a - b) ** 2 / (b ** 2 + 0.01)))


def quarter_noise(name):
    folder = os.path.join(HERE, name)
    cwd = os.getcwd()
    os.chdir(folder)  # relative mesh and texture paths
    try:
        w, h = mi.load_file("scene.xml").sensors()[0].film().size()
        scene = mi.load_file("scene.xml", spp=64, resx=int(w) // 4, resy=int(h) // 4)
        a, b = (np.array(mi.render(scene, spp=64, seed=s), dtype=np.float64) for s in (1, 2))
    finally:
        os.chdir(cwd)
    return relmse(a, b) / 2


def store(name, value, made_with):
    path = os.path.join(HERE, name, "reference.json")
    info = json.load(open(path))
    info["mitsuba_quarter_64spp_noise"] = value
    info["mitsuba_quarter_64spp_noise_made_with"] = made_with
    with open(path, "w") as f:
        json.dump(info, f, indent=2)
        f.write("\n")
    print(name, value)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="*")
    ap.add_argument("--same-as", nargs="+", metavar=("SRC", "SCENE"))
    args = ap.parse_args()
    mi.set_variant("llvm_ad_rgb")
    for name in args.scenes:
        store(name, quarter_noise(name),
              "tests/data/scenes/mitsuba_quarter_noise.py (mitsuba %s, llvm_ad_rgb)" % mi.__version__)
    if args.same_as:
        src, *copies = args.same_as
        value = json.load(open(os.path.join(HERE, src, "reference.json")))["mitsuba_quarter_64spp_noise"]
        for name in copies:
            store(name, value, "%s's figure: this scene is %s scaled, its reference a copy" % (src, src))


if __name__ == "__main__":
    sys.exit(main())
