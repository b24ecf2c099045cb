#!/usr/bin/env python3
"""Issue 14's "what a feature costs when used": the Cornell box (scenes/cornell-box.toml) and
variants of it that each call for one feature more (the tall box's material or texture, a
sphere, an environment), written to OUT_DIR as <feature>.toml (base.toml: the box itself).

    python3 tools/features/cornell_variants.py scenes/cornell-box.toml OUT_DIR

Each variant differs from the box in that one place; timing each with its specialised
pipeline against the box's gives what using the feature costs (the light transport it
changes included: a glass box sends paths through it, so the rays per sample change too).
"""
import pathlib
import sys

TALL = '[materials.TallBox]\ntype = "diffuse"\nalbedo = [0.725, 0.71, 0.68]\n'


def material(kind, extra):
    return f'[materials.TallBox]\ntype = "{kind}"\n{extra}'


VARIANTS = {
    "metal": ("tall", material("metal", 'albedo = [0.9, 0.9, 0.9]\nroughness = 0.0\n')),
    "rough_metal": ("tall", material("metal", 'albedo = [0.9, 0.9, 0.9]\nroughness = 0.3\n')),
    "glass": ("tall", material("glass", 'ior = 1.5\n')),
    "rough_glass": ("tall", material("glass", 'ior = 1.5\nroughness = 0.3\n')),
    "plastic": ("tall", material("plastic", 'albedo = [0.725, 0.71, 0.68]\nroughness = 0.2\n')),
    # The living room's wood on the tall box (its quads' uvs); the path is filled in below.
    "textures": ("tall", material("diffuse", 'albedo = [1.0, 1.0, 1.0]\ntexture = "{wood}"\n')),
    # A diffuse ball on the floor, left of the short box.
    "spheres": ("end", '\n[[sphere]]\ncenter = [-0.5, 0.25, 0.6]\nradius = 0.25\nmaterial = "Floor"\n'),
    # A dim sky, seen through the open front.
    "constant_environment": ("end", '\n[environment]\nradiance = [0.3, 0.3, 0.3]\n'),
}


def main():
    src = pathlib.Path(sys.argv[1]).read_text()
    out = pathlib.Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    if TALL not in src:
        sys.exit("the tall box's material is not where this script expects it")
    (out / "base.toml").write_text(src)
    wood = (pathlib.Path(sys.argv[1]).resolve().parent / "living-room/textures/wood.jpg")
    for name, (where, text) in VARIANTS.items():
        text = text.replace("{wood}", str(wood))
        if where == "tall":
            scene = src.replace(TALL, text, 1)
        else:
            # Tables must follow the top-level keys: append at the end, where [[quad]] etc. are.
            scene = src + text
        (out / f"{name}.toml").write_text(scene)
    print(" ".join(str(out / f"{n}.toml") for n in ["base", *VARIANTS]))


if __name__ == "__main__":
    main()
