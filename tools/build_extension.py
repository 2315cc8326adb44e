"""Build the Blender extension zips (one per platform, wheels bundled) and validate them.

Usage::

    python tools/build_extension.py              # download wheels, build + validate per-platform zips
                                                 # (this platform's with its kernels compiled inside)
    python tools/build_extension.py --no-wheels  # one zip without wheels (for a Blender whose
                                                 # Python already has numba, pydicom, ...: the tests)
    python tools/build_extension.py --no-kernels # kernels compiled on first use in Blender instead
    python tools/build_extension.py --validate   # only validate blender_manifest.toml

Output: ``dist/anatomesh-<version>-<platform>.zip`` (or ``dist/anatomesh-<version>.zip`` with
``--no-wheels``). Work happens in ``build/extension/`` (a copy of the checkout) and downloaded
wheels are kept in ``build/wheels/``, so the checkout itself never changes.

The wheels are exactly the files named in ``blender_manifest.toml``; each is fetched with
``pip download --only-binary=:all: --no-deps --python-version 3.11 --platform <its tag>``. The
builder is Blender's own ``blender_ext.py`` (shipped in the bpy wheel and in every Blender 4.2+),
found automatically or given with ``--blender-ext`` / ``$BLENDER_EXT``.
"""
from __future__ import annotations

import argparse
import glob
import importlib.util
import os
import platform
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from typing import List, Optional

try:
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python < 3.11
    tomllib = None

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tools"))
import build_wheel  # noqa: E402  (the portable kernels)

sys.path.pop(0)
MANIFEST = "blender_manifest.toml"
#: the module name Blender gives an extension installed from a file (the "user_default" repository)
EXTENSION_MODULE = "bl_ext.user_default.anatomesh"
#: the platform tag of the zip the kernels compiled here belong in (``--split-platforms`` names)
_BUILDER_PLATFORM = {("linux", "x86_64"): "linux_x64", ("linux", "aarch64"): "linux_arm64",
                     ("darwin", "arm64"): "macos_arm64", ("darwin", "x86_64"): "macos_x64",
                     ("win32", "AMD64"): "windows_x64"}.get((sys.platform, platform.machine()), "?")
PYTHON_VERSION = "3.11"
#: top-level entries never copied to the staging folder (developer-only; the manifest's
#: exclusion patterns would drop most of them anyway, and a virtualenv would be gigabytes)
_TOP_SKIP = {"build", "dist", "wheels", "venv", "out", "demo_out", "tests", "benchmarks", "examples",
             "tools", "data", "web", "docs"}  # web/: the viewer's npm sources (built into app/web/viewer)
_ANY_SKIP = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc", "*.egg-info")


def _stage_ignore(root: Path):
    def ignore(directory, names):
        skipped = set(_ANY_SKIP(directory, names))
        if Path(directory).resolve() == root.resolve():
            skipped |= {n for n in names if n.startswith(".") or n in _TOP_SKIP}
        return skipped

    return ignore

def find_blender_ext(explicit: Optional[str] = None) -> Path:
    """Path of Blender's ``blender_ext.py`` (argument, ``$BLENDER_EXT``, or inside the bpy package)."""
    for cand in (explicit, os.environ.get("BLENDER_EXT")):
        if cand:
            p = Path(cand)
            if p.is_file():
                return p
            sys.exit(f"error: {p}: no such file; give the path of blender_ext.py")
    spec = importlib.util.find_spec("bpy")
    roots = list(spec.submodule_search_locations or []) if spec else []
    for root in roots:
        hits = sorted(glob.glob(os.path.join(root, "*", "scripts", "addons_core", "bl_pkg", "cli",
                                             "blender_ext.py")))
        if hits:
            return Path(hits[-1])
    sys.exit("error: blender_ext.py not found: install the bpy module (pip install bpy==5.0.1) or "
             "pass --blender-ext /path/to/blender/<version>/scripts/addons_core/bl_pkg/cli/blender_ext.py")


def manifest_wheels(manifest_text: str) -> List[str]:
    """The ``wheels`` list of the manifest (paths relative to the extension root)."""
    if tomllib is not None:
        return list(tomllib.loads(manifest_text).get("wheels", []))
    block = re.search(r"^wheels\s*=\s*\[(.*?)\]", manifest_text, re.S | re.M)
    return re.findall(r'"([^"]+)"', block.group(1)) if block else []


def strip_wheels(manifest_text: str) -> str:
    """The manifest without ``wheels`` and ``platforms`` (a zip that runs on any platform)."""
    for key in ("wheels", "platforms"):
        manifest_text = re.sub(rf"^{key}\s*=\s*\[.*?\]\s*\n", "", manifest_text, flags=re.S | re.M)
    return manifest_text


def download_wheel(filename: str, cache: Path) -> Path:
    """Fetch one wheel named exactly ``filename`` into ``cache`` (kept between builds)."""
    target = cache / filename
    if target.exists():
        return target
    parts = filename[:-4].split("-")
    if len(parts) < 5:
        sys.exit(f"error: {filename}: not a wheel file name (name-version-python-abi-platform.whl)")
    name, version, abi, plat = parts[0], parts[1], parts[-2], parts[-1]
    cmd = [sys.executable, "-m", "pip", "download", "--only-binary=:all:", "--no-deps",
           "--python-version", PYTHON_VERSION, "-d", str(cache), "-q", f"{name}=={version}"]
    if plat != "any":
        for tag in plat.split("."):
            cmd += ["--platform", tag]
        cmd += ["--implementation", "cp", "--abi", abi]
    print(f"downloading {filename}")
    subprocess.run(cmd, check=True)
    if not target.exists():
        got = sorted(p.name for p in cache.glob(f"{name}-{version}-*.whl"))
        sys.exit(f"error: pip gave {got or 'nothing'} instead of {filename}; update the wheels list in "
                 f"{MANIFEST}")
    return target


def stage(source: Path, dest: Path) -> Path:
    """A clean copy of the checkout to build from."""
    if dest.exists():
        shutil.rmtree(dest)
    shutil.copytree(source, dest, ignore=_stage_ignore(source), symlinks=False)
    return dest


def run_ext(blender_ext: Path, *args: str) -> None:
    cmd = [sys.executable, str(blender_ext), *args]
    print("$", " ".join(cmd))
    subprocess.run(cmd, check=True)


def add_portable_kernels(staged: Path, steps: Optional[str] = None) -> str:
    """numba's kernels (the warm-up's default flow, or its ``steps``) compiled for a generic CPU
    into the staged extension, under the module name Blender gives it (``tools/build_wheel.py``
    says how they are found); the manifest keeps them in the zip. Returns the marker line
    (platform, machine, Python, numba)."""
    line = build_wheel.compile_portable_kernels(staged, name=EXTENSION_MODULE, steps=steps)
    build_wheel.write_marker(staged, [line])
    text = (staged / MANIFEST).read_text()
    for pattern in ('  "__pycache__/",\n', '  "*.nbi",\n', '  "*.nbc",\n'):
        assert pattern in text, f"{MANIFEST} no longer excludes {pattern.strip()}"
        text = text.replace(pattern, "")
    (staged / MANIFEST).write_text(text)
    return line


def drop_portable_kernels(zip_path: Path) -> None:
    """Rewrite a zip without the kernels (a platform they were not compiled for)."""
    kept = zip_path.with_suffix(".tmp")
    with zipfile.ZipFile(zip_path) as old, zipfile.ZipFile(kept, "w", zipfile.ZIP_DEFLATED) as new:
        for item in old.infolist():
            if not item.filename.endswith((".nbi", ".nbc", build_wheel.MARKER)):
                new.writestr(item, old.read(item))
    kept.replace(zip_path)


def build(out_dir: Path, *, wheels: bool = True, kernels: bool = True, kernel_steps: Optional[str] = None,
          blender_ext: Optional[Path] = None, source: Path = REPO, work: Optional[Path] = None) -> List[Path]:
    """Build (and validate) the extension zips; returns their paths. ``kernels``: with numba's
    kernels compiled for a generic CPU of this platform (in this platform's zip only), those of
    the warm-up's default flow or of its ``kernel_steps``."""
    blender_ext = blender_ext or find_blender_ext()
    work = work or (source / "build")
    staged = stage(source, work / "extension" / "anatomesh")
    if kernels:
        print("portable kernels:", add_portable_kernels(staged, kernel_steps))
    manifest = (staged / MANIFEST).read_text()
    if wheels:
        cache = work / "wheels"
        cache.mkdir(parents=True, exist_ok=True)
        (staged / "wheels").mkdir(exist_ok=True)
        for rel in manifest_wheels(manifest):
            whl = download_wheel(Path(rel).name, cache)
            shutil.copy2(whl, staged / rel)
    else:
        (staged / MANIFEST).write_text(strip_wheels(manifest))
    out_dir = out_dir.resolve()
    out_dir.mkdir(parents=True, exist_ok=True)  # the builder does not create it
    before = set(out_dir.glob("*.zip"))
    for old in before:  # a stale zip of the same name would be reported as this build's
        if old.name.startswith("anatomesh-"):
            old.unlink()
    args = ["build", "--source-dir", str(staged), "--output-dir", str(out_dir)]
    if wheels:
        args.append("--split-platforms")
    run_ext(blender_ext, *args)
    zips = sorted(out_dir.glob("anatomesh-*.zip"))
    if not zips:
        sys.exit(f"error: the builder wrote no zip into {out_dir}")
    for z in zips:
        if kernels and wheels and _BUILDER_PLATFORM not in z.name:
            drop_portable_kernels(z)
        run_ext(blender_ext, "validate", str(z))
    return zips


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--no-wheels", action="store_true", help="one zip without bundled wheels")
    ap.add_argument("--no-kernels", action="store_true",
                    help="without numba's kernels compiled for a generic CPU (they compile on first use)")
    ap.add_argument("--out", default=str(REPO / "dist"), help="output folder (default: dist/)")
    ap.add_argument("--blender-ext", help="path of Blender's blender_ext.py")
    ap.add_argument("--validate", action="store_true", help="only validate the manifest")
    args = ap.parse_args(argv)
    blender_ext = find_blender_ext(args.blender_ext)
    if args.validate:
        run_ext(blender_ext, "validate", str(REPO))
        return 0
    for z in build(Path(args.out), wheels=not args.no_wheels, kernels=not args.no_kernels, blender_ext=blender_ext):
        print(f"built {z} ({z.stat().st_size / 2**20:.1f} MiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
