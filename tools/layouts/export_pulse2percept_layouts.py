#!/usr/bin/env python
"""Write the electrode layouts of real implants to ``config/layouts/<name>.yaml`` from
pulse2percept 0.11 (a dev dependency; run only to regenerate the shipped files):

    .venv/bin/python tools/layouts/export_pulse2percept_layouts.py

The shipped files are what RASPV reads at run time, so a user without pulse2percept gets every
preset; ``tests/spv/test_implant_layouts.py`` checks them against pulse2percept when it is
installed. Positions are device-local (the array's own frame, before any placement), µm, as
pulse2percept gives them; electrodes that make no phosphene are left out: those it marks as
not activated (ICVP's reference and counter shafts) and the suprachoroidal arrays' two large
return electrodes (R1, R2).
"""
from __future__ import annotations

import sys
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "config" / "layouts"

# our name -> (module, class, description)
LAYOUTS = {
    "argus_i": ("retina", "ArgusI", "Second Sight Argus I: 4 x 4 disk electrodes (260/520 µm), 800 µm pitch"),
    "argus_ii": ("retina", "ArgusII", "Second Sight Argus II: 6 x 10 disk electrodes (225 µm), 575 µm pitch"),
    "alpha_ims": ("retina", "AlphaIMS", "Retina Implant AG Alpha-IMS: 1500 photodiode electrodes, 72 µm pitch"),
    "alpha_ams": ("retina", "AlphaAMS", "Retina Implant AG Alpha-AMS: 1600 photodiode electrodes, 70 µm pitch"),
    "prima": ("retina", "PRIMA", "Pixium PRIMA: 378 photovoltaic hexagonal pixels, 100 µm pitch, 2 mm wide"),
    "prima75": ("retina", "PRIMA75", "PRIMA 75 µm (Lorach 2015): 142 photovoltaic pixels, 1 mm wide"),
    "prima55": ("retina", "PRIMA55", "PRIMA 55 µm (Ho 2019): 250 photovoltaic pixels, 1 mm wide"),
    "prima40": ("retina", "PRIMA40", "PRIMA 40 µm (Ho 2019): 502 photovoltaic pixels, 1 mm wide"),
    "bva24": ("retina", "Suprachoroidal24", "Bionic Vision Australia 24-channel suprachoroidal array (Ayton 2014)"),
    "bva44": ("retina", "Suprachoroidal44", "Bionic Vision Technologies 44-channel suprachoroidal array (Allen 2021)"),
    "orion": ("cortex", "Orion", "Second Sight Orion: 60 epicortical disk electrodes on a hexagonal grid"),
    "icvp": ("cortex", "ICVP", "Intracortical Visual Prosthesis: 16 iridium shafts, 400 µm hexagonal pitch"),
}

RETURNS = ("R1", "R2")


def main() -> int:
    import pulse2percept
    from pulse2percept.implants import cortex, retina

    OUT.mkdir(parents=True, exist_ok=True)
    for name, (kind, cls_name, description) in LAYOUTS.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            implant = getattr(retina if kind == "retina" else cortex, cls_name)()
        rows = []
        for ename, e in zip(implant.electrode_names, implant.electrode_objects):
            if not getattr(e, "activated", True) or (cls_name.startswith("Suprachoroidal") and ename in RETURNS):
                continue
            radius = float(getattr(e, "r", getattr(e, "radius", 0.0)) or 0.0)
            rows.append(f"  - [\"{ename}\", {float(e.x):.4f}, {float(e.y):.4f}, {radius:.2f}]")
        placement = getattr(implant, "placement", None) or ("epiretinal" if kind == "retina" else "epicortical")
        text = "\n".join([
            f"# Electrode layout exported from pulse2percept {pulse2percept.__version__} "
            f"(pulse2percept.implants.{kind}.{cls_name}()) by tools/layouts/export_pulse2percept_layouts.py.",
            f"# Device-local frame, µm: x right, y down on the {'retina (towards the lower visual field)' if kind == 'retina' else 'cortex'}.",
            f"name: {name}",
            f"description: \"{description}\"",
            f"target: {kind}",
            f"placement: {placement}",
            f"source: \"pulse2percept {pulse2percept.__version__} {cls_name}()\"",
            "electrodes:   # [name, x_um, y_um, radius_um]",
            *rows, ""])
        (OUT / f"{name}.yaml").write_text(text)
        print(f"{name}: {len(rows)} electrodes -> {OUT / (name + '.yaml')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
