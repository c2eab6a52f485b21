"""`python -m ipfn.blender [ZIP]`: writes the Blender add-on as a zip (default
`ipfn_blender.zip`) to install from Blender's Preferences > Add-ons > Install.

The zip holds the add-on (`addon.py` as `ipfn_blender/__init__.py`) and this installed ipfn package, compiled
part included, under `ipfn_blender/vendor/`. The compiled part is an abi3 module: it loads in
any CPython from 3.9 on, Blender's own included, on the same platform.
"""

import os
import sys
import zipfile

import ipfn


def write_zip(path):
    package = os.path.dirname(os.path.abspath(ipfn.__file__))
    addon = os.path.join(package, "blender", "addon.py")
    tmp = path + ".tmp"
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        z.write(addon, "ipfn_blender/__init__.py")
        for root, dirs, files in os.walk(package):
            dirs[:] = [d for d in dirs if d != "__pycache__"]
            for name in files:
                full = os.path.join(root, name)
                inside = os.path.relpath(full, os.path.dirname(package))
                z.write(full, os.path.join("ipfn_blender", "vendor", inside))
    os.replace(tmp, path)
    return path


def main(argv):
    if len(argv) > 1 or (argv and argv[0] in ("-h", "--help")):
        print(__doc__.strip())
        return 0 if argv and argv[0] in ("-h", "--help") else 2
    out = argv[0] if argv else "ipfn_blender.zip"
    write_zip(out)
    print(f"wrote {out}: Blender > Edit > Preferences > Add-ons > Install..., then enable "
          '"Material: ipfn texture"')
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
