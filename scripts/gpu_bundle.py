"""The offline bundle a CUDA machine without package access needs to run the study: the pinned
wheels of pyproject.toml for one Python version and platform (manylinux x86_64 by default), the
whole dependency closure resolved and pinned, in a folder and a tarball that `scripts/gpu_check.sh`
installs with `uv pip install --no-index --find-links` (or pip's).

    python3 scripts/gpu_bundle.py --dry-run                 # the plan: what would be fetched, nothing fetched
    python3 scripts/gpu_bundle.py --dry-run --resolve       # ... and the closure (uv pip compile: metadata only)
    python3 scripts/gpu_bundle.py [--python 3.12] [--out build/gpu-bundle] [--no-video] [--gl]
                                  [--exclude-newer 2026-12-01T00:00:00Z]

What goes in:
- every dependency of pyproject.toml, at its pin, and pytest (the references' tests run there);
  the CUDA builds are those PyPI serves for Linux: Mitsuba's and Dr.Jit's wheels carry their CUDA
  variants (cuda_ad_rgb; the driver's libcuda and OptiX come with the machine), and PyPI's Linux
  torch is the CUDA build, with its nvidia-* libraries (~4 GB: --no-video leaves ColorVideoVDP,
  torch and torchvision out, for a machine that will not judge the JOD);
- what a GPU run does not need stays out: the report's browser test (selenium; Debian's chromium),
  the paper's PDF test (pdfminer.six; TeX is Debian's), pytest-xdist;
- with --gl, libglvnd's Debian packages (`apt-get download`), which scripts/gpu_check.sh unpacks
  where the NVIDIA driver mounts libEGL_nvidia without the dispatch library.

Steps: requirements.txt (the top-level pins) and constraints.txt (the versions of the checkout's
.venv, which the suite passed with: --no-match-venv drops them); lock.txt (`uv pip compile --python-version X
--python-platform x86_64-manylinux_2_28`, the closure with every version pinned; --exclude-newer
makes it reproducible later); wheels/ (`pip download --no-deps --only-binary=:all:` of each locked
line for that platform and Python; a pure-Python package PyPI has only as an sdist is built once
here into a py3-none-any wheel, anything else is refused); then the tarball gpu-bundle-<python>.tar.
Exit status 2 with one line for bad input or a step that fails.
"""
from __future__ import annotations

import argparse
import json
import re
import shlex
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# not needed on a GPU run: the report's browser test, the paper's PDF test, the suite's parallelism
LEFT_OUT = {"selenium", "pdfminer-six", "pytest-xdist"}
VIDEO = {"cvvdp", "torch", "torchvision"}          # ColorVideoVDP and its torch (the CUDA build)
GL_DEBS = ["libglvnd0", "libegl1", "libgl1", "libglx0", "libopengl0"]
PLATFORMS = {"x86_64": ["manylinux_2_28_x86_64", "manylinux_2_27_x86_64", "manylinux_2_17_x86_64",
                        "manylinux2014_x86_64", "linux_x86_64"]}


class BundleError(RuntimeError):
    """A step that cannot be done; the message says which and why (one line)."""


def _name(req: str) -> str:
    """A requirement's normalised project name (PEP 503)."""
    m = re.match(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)", req)
    if not m:
        raise BundleError(f"pyproject.toml: {req!r} is not a requirement")
    return re.sub(r"[-_.]+", "-", m.group(1)).lower()


def requirements(pyproject: Path, video: bool = True) -> list[str]:
    """The bundle's top-level requirements, as pyproject.toml pins them: its dependencies and its
    test extra, less LEFT_OUT (and VIDEO without `video`)."""
    try:
        project = tomllib.loads(Path(pyproject).read_text())["project"]
    except (OSError, tomllib.TOMLDecodeError, KeyError) as exc:
        raise BundleError(f"{pyproject}: cannot read its [project] ({exc})") from None
    reqs = list(project.get("dependencies", [])) + list(project.get("optional-dependencies", {}).get("test", []))
    skip = LEFT_OUT | (set() if video else VIDEO)
    return [r for r in reqs if _name(r) not in skip]


def plan(args) -> dict:
    """Every command the bundle takes, in order, without running any."""
    out = Path(args.out)
    py = args.python
    cp = "cp" + py.replace(".", "")
    plats = PLATFORMS[args.arch]
    uv = shutil.which("uv") or str(Path(sys.executable).parent / "uv")     # scripts/setup.sh's, in .venv
    compile_cmd = [uv, "pip", "compile", "--no-header", "--python-version", py,
                   "--python-platform", f"{args.arch}-manylinux_2_28", "-o", str(out / "lock.txt"),
                   str(out / "requirements.txt")]
    if args.exclude_newer:
        compile_cmd[3:3] = ["--exclude-newer", args.exclude_newer]
    if args.match_venv:      # the versions the suite passed with here, where the ranges allow them
        compile_cmd[3:3] = ["-c", str(out / "constraints.txt")]
    download = [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:", "--python-version", py,
                "--implementation", "cp", "--abi", cp, "--abi", "abi3", "--abi", "none"]
    for p in plats:
        download += ["--platform", p]
    download += ["-d", str(out / "wheels")]
    steps = [{"step": "requirements", "file": str(out / "requirements.txt"),
              "constraints": f"{out / 'constraints.txt'} (uv pip freeze of {args.match_venv})" if args.match_venv
              else None},
             {"step": "resolve", "cmd": compile_cmd},
             {"step": "download", "cmd": download + ["-r", str(out / "lock.txt")]}]
    if args.gl:
        steps.append({"step": "gl", "cmd": ["apt-get", "download", *GL_DEBS], "cwd": str(out / "gl")})
    steps.append({"step": "tarball", "cmd": ["tar", "-cf", str(out.parent / f"gpu-bundle-{py}.tar"),
                                              "-C", str(out.parent), out.name]})
    return {"python": py, "platforms": plats, "video": not args.no_video, "out": str(out),
            "requirements": requirements(args.pyproject, not args.no_video), "left_out":
            sorted(LEFT_OUT | (set() if not args.no_video else VIDEO)), "steps": steps}


def _run(cmd, what: str, cwd=None) -> str:
    try:
        r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    except OSError as exc:
        raise BundleError(f"{what}: cannot run {cmd[0]} ({exc.strerror or exc})") from None
    if r.returncode != 0:
        tail = (r.stderr or r.stdout).strip().splitlines()[-1:] or ["(no output)"]
        raise BundleError(f"{what} failed (exit {r.returncode}): {tail[0]}")
    return r.stdout


def _locked(lock: Path) -> list[str]:
    return [ln.split(";")[0].strip() for ln in lock.read_text().splitlines()
            if ln.strip() and not ln.lstrip().startswith("#")]


def write_inputs(p: dict, venv: str | None) -> None:
    """requirements.txt, and constraints.txt from the environment `venv` (its packages' versions,
    less the project itself and what the bundle leaves out)."""
    out = Path(p["out"])
    out.mkdir(parents=True, exist_ok=True)
    (out / "requirements.txt").write_text("\n".join(p["requirements"]) + "\n")
    if venv:
        py = Path(venv) / "bin" / "python"
        uv = p["steps"][1]["cmd"][0]
        frozen = _run([uv, "pip", "freeze", "--python", str(py)], f"uv pip freeze of {venv}")
        keep = [ln for ln in frozen.splitlines() if "==" in ln and not ln.startswith("-e")
                and _name(ln) not in set(p["left_out"])]
        (out / "constraints.txt").write_text("\n".join(keep) + "\n")


def build(p: dict, venv: str | None) -> None:
    """Run the plan's steps (see the module docstring)."""
    out = Path(p["out"])
    (out / "wheels").mkdir(parents=True, exist_ok=True)
    write_inputs(p, venv)
    for s in p["steps"][1:]:
        print(f"gpu_bundle: {s['step']}: {shlex.join(s['cmd'])}", flush=True)
        if s["step"] == "download":
            try:                        # one pip for the whole lock; line by line where that fails
                _run(s["cmd"], "pip download")
            except BundleError:
                base = s["cmd"][:-2]
                for line in _locked(out / "lock.txt"):
                    try:
                        _run(base + [line], f"pip download {line}")
                    except BundleError:
                        _sdist_wheel(line, out / "wheels")
        else:
            if s.get("cwd"):
                Path(s["cwd"]).mkdir(parents=True, exist_ok=True)
            _run(s["cmd"], s["step"], s.get("cwd"))
    (out / "plan.json").write_text(json.dumps(p, indent=1) + "\n")


def _sdist_wheel(line: str, wheels: Path) -> None:
    """A package PyPI has no wheel of for the platform: built here, kept only if pure Python."""
    before = set(wheels.glob("*.whl"))
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-binary", ":all:", "-w", str(wheels), line],
         f"no wheel of {line} for the platform, and building one")
    for w in set(wheels.glob("*.whl")) - before:
        if not w.name.endswith(("-py3-none-any.whl", "-py2.py3-none-any.whl")):
            w.unlink()
            raise BundleError(f"{line}: PyPI has no wheel for the platform and its sdist builds {w.name}, "
                              "not a pure-Python wheel; build it on the GPU machine's platform")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--python", default="3.12", help="the GPU machine's Python, X.Y (default 3.12)")
    ap.add_argument("--arch", default="x86_64", help="the machine's architecture (x86_64)")
    ap.add_argument("--out", default=str(ROOT / "build" / "gpu-bundle"), help="the bundle's folder")
    ap.add_argument("--pyproject", default=str(ROOT / "pyproject.toml"))
    ap.add_argument("--no-video", action="store_true", help="leave ColorVideoVDP, torch and torchvision out")
    ap.add_argument("--gl", action="store_true", help="also libglvnd's .debs (apt-get download)")
    ap.add_argument("--exclude-newer", default=None, help="resolve as of this date (uv's --exclude-newer)")
    venv = ROOT / ".venv"
    ap.add_argument("--match-venv", default=str(venv) if (venv / "bin" / "python").exists() else None,
                    help="constrain the closure to this environment's versions (default: the checkout's .venv)")
    ap.add_argument("--no-match-venv", dest="match_venv", action="store_const", const=None,
                    help="resolve the newest versions the pins allow")
    ap.add_argument("--dry-run", action="store_true", help="print the plan as JSON; fetch nothing")
    ap.add_argument("--resolve", action="store_true", help="with --dry-run: resolve the closure (metadata only)")
    a = ap.parse_args(argv)
    if not re.fullmatch(r"3\.\d{1,2}", a.python):
        print(f"gpu_bundle: --python {a.python!r}: expected X.Y, e.g. 3.12", file=sys.stderr)
        return 2
    if a.arch not in PLATFORMS:
        print(f"gpu_bundle: --arch {a.arch!r}: expected one of {', '.join(PLATFORMS)}", file=sys.stderr)
        return 2
    try:
        p = plan(a)
        if a.dry_run:
            if a.resolve:
                out = Path(a.out)
                write_inputs(p, a.match_venv)
                _run(p["steps"][1]["cmd"], "resolve")
                p["lock"] = _locked(out / "lock.txt")
            print(json.dumps(p, indent=1))
            return 0
        build(p, a.match_venv)
    except BundleError as exc:
        print(f"gpu_bundle: {exc}", file=sys.stderr)
        return 2
    print(f"gpu_bundle: {p['out']} and {Path(p['out']).parent / f'gpu-bundle-{a.python}.tar'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
