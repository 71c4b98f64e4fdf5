# SPDX-License-Identifier: LGPL-2.1-or-later
"""Damaged copies of corpus parts for the readers' tests: tests/parts/damaged/.

    python3 tools/make_damaged_parts.py [--probe] [--freecadcmd CMD]

Writes, from three small corpus files (a STEP, a BREP and an FCStd of tests/parts/), copies cut
at several offsets, with digits of numbers changed, with entity references #N pointing nowhere
or at entities of the wrong type, without the STEP header, with garbage bytes, and a few files
that are not parts at all.  Deterministic: the same bytes on every run (a fixed seed, fixed zip
dates), so the committed files are this script's output.

--probe reads every damaged file with FreeCAD 0.20 in its own process (``Part.read`` for STEP
and BREP, ``FreeCAD.openDocument`` for FCStd), records how it ends (exit status, signal, the
exception) and with ``bin/bsplinecam check``, then writes tests/parts/damaged/README.md.
"""

from __future__ import annotations

import argparse
import io
import os
import random
import re
import signal
import subprocess
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PARTS = ROOT / "tests" / "parts"
OUT = PARTS / "damaged"
SEED = 20261206
STEP_SOURCE = PARTS / "2225_SMD.stp"
BREP_SOURCE = PARTS / "mal_vis.brep"
FCSTD_SOURCE = PARTS / "test_holes00.fcstd"
#: A real number of a STEP or BREP file: digits with a decimal point, sign and exponent optional.
_REAL = re.compile(rb"-?\d+\.\d*(?:[eE][-+]?\d+)?")
#: An entity reference inside a STEP record (not the "#N=" that names the record).
_REF = re.compile(rb"#(\d+)(?!\d|\s*=)")
_DATE = (2026, 12, 6, 0, 0, 0)


def cut(data: bytes, fraction: float) -> bytes:
    """The first ``fraction`` of the bytes (a cut anywhere, mid-line and mid-number included)."""
    return data[: int(len(data) * fraction)]


def change_digits(data: bytes, every: int, rng: random.Random) -> bytes:
    """Every ``every``-th real number with one of its digits replaced by another digit."""
    count = 0

    def repl(match: re.Match) -> bytes:
        nonlocal count
        count += 1
        text = bytearray(match.group(0))
        if count % every:
            return bytes(text)
        spots = [i for i, c in enumerate(text) if chr(c).isdigit()]
        i = rng.choice(spots)
        text[i] = ord(rng.choice([d for d in "0123456789" if d != chr(text[i])]))
        return bytes(text)

    return _REAL.sub(repl, data)


def data_section(data: bytes) -> tuple[int, int]:
    start = data.index(b"DATA;") + len(b"DATA;")
    return start, data.index(b"ENDSEC;", start)


def break_refs(data: bytes, every: int, dangling: bool, rng: random.Random) -> bytes:
    """In the DATA section, every ``every``-th reference #N made to point at no entity
    (``dangling``) or at another existing entity, most often of the wrong type."""
    start, end = data_section(data)
    ids = [int(m) for m in re.findall(rb"^#(\d+)\s*=", data, flags=re.M)]
    top = max(ids)
    count = 0

    def repl(match: re.Match) -> bytes:
        nonlocal count
        count += 1
        if count % every:
            return match.group(0)
        target = top + 1000 + count if dangling else rng.choice(ids)
        return b"#%d" % target

    return data[:start] + _REF.sub(repl, data[start:end]) + data[end:]


def self_refs(data: bytes, every: int) -> bytes:
    """Every ``every``-th record's first reference made to point at the record itself (a cycle)."""
    out = []
    for n, line in enumerate(data.split(b"\n")):
        m = re.match(rb"#(\d+)\s*=", line)
        if m and n % every == 0:
            line = _REF.sub(b"#" + m.group(1), line, count=1) if _REF.search(line[m.end():]) \
                else line
        out.append(line)
    return b"\n".join(out)


def drop_header(data: bytes) -> bytes:
    start = data.index(b"HEADER;")
    end = data.index(b"ENDSEC;", start) + len(b"ENDSEC;")
    return data[:start] + data[end:].lstrip(b"\r\n")


def garbage(data: bytes, at: float, size: int, rng: random.Random) -> bytes:
    """``size`` random bytes put in at the fraction ``at`` of the file."""
    pos = int(len(data) * at)
    return data[:pos] + bytes(rng.randrange(256) for _ in range(size)) + data[pos:]


def zip_with(source: bytes, change: Callable[[str, bytes], bytes | None]) -> bytes:
    """A copy of the zip ``source`` with each member passed through ``change`` (None drops it),
    written with fixed dates so the bytes are the same on every run."""
    buf = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(source)) as zin, \
            zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            body = change(info.filename, zin.read(info.filename))
            if body is not None:
                zout.writestr(zipfile.ZipInfo(info.filename, _DATE), body,
                              compress_type=zipfile.ZIP_DEFLATED)
    return buf.getvalue()


def damaged() -> dict[str, tuple[bytes, str]]:
    """File name -> (bytes, what was done), in a fixed order."""
    rng = random.Random(SEED)
    step = STEP_SOURCE.read_bytes()
    brep = BREP_SOURCE.read_bytes()
    fcstd = FCSTD_SOURCE.read_bytes()
    s, b, f = STEP_SOURCE.name, BREP_SOURCE.name, FCSTD_SOURCE.name
    files: dict[str, tuple[bytes, str]] = {}

    def add(name: str, data: bytes, what: str) -> None:
        files[name] = (data, what)

    add("step_cut_header.stp", step[:400], f"{s}: the first 400 bytes (cut inside the HEADER)")
    for pct in (10, 50):
        add(f"step_cut_{pct:02d}.stp", cut(step, pct / 100),
            f"{s}: the first {pct} % of the bytes (cut mid-record, no ENDSEC, no END-ISO)")
    add("step_cut_end.stp", step[: step.rindex(b"ENDSEC;")],
        f"{s}: the last ENDSEC and END-ISO-10303-21 removed (all records whole)")
    add("step_digits.stp", change_digits(step, 7, rng),
        f"{s}: one digit changed in every 7th real number (points off their curves and faces)")
    add("step_dangling_refs.stp", break_refs(step, 40, True, rng),
        f"{s}: every 40th reference #N in DATA made to point at no entity")
    add("step_wrong_refs.stp", break_refs(step, 25, False, rng),
        f"{s}: every 25th reference #N in DATA made to point at another entity, mostly of the "
        "wrong type")
    add("step_self_refs.stp", self_refs(step, 9),
        f"{s}: the first reference of every 9th record made to point at the record itself")
    add("step_no_header.stp", drop_header(step), f"{s}: the HEADER section removed")
    add("step_garbage.stp", garbage(step, 0.5, 4096, rng),
        f"{s}: 4096 random bytes (NULs and non-ASCII included) put in at the middle")
    add("empty.step", b"", "an empty file")
    add("not_a_part.step", b'{"name": "net", "control_points": [[0, 0, 0]]}\n',
        "a JSON control net named .step")
    add("binary.stp", bytes(rng.randrange(256) for _ in range(2048)), "2048 random bytes")
    add("brep_cut_50.brep", cut(brep, 0.5), f"{b}: the first half of the bytes")
    add("brep_digits.brep", change_digits(brep, 5, rng),
        f"{b}: one digit changed in every 5th real number")
    add("brep_garbage.brep", garbage(brep, 0.4, 2048, rng),
        f"{b}: 2048 random bytes put in at 40 %")
    add("brep_no_header.brep", brep[brep.index(b"Locations"):],
        f"{b}: the 'DBRep_DrawableShape' / 'CASCADE Topology V1' lines removed")
    add("fcstd_cut_50.fcstd", cut(fcstd, 0.5), f"{f}: the first half of the zip")
    add("fcstd_bad_xml.fcstd",
        zip_with(fcstd, lambda n, d: d[: len(d) // 2] if n == "Document.xml" else d),
        f"{f}: a whole zip whose Document.xml is cut in half")
    add("fcstd_cut_brep.fcstd",
        zip_with(fcstd, lambda n, d: d[: len(d) // 3] if n.endswith((".brp", ".brep")) else d),
        f"{f}: a whole zip whose shapes (*.brp) are each cut to a third")
    add("fcstd_no_shapes.fcstd",
        zip_with(fcstd, lambda n, d: None if n.endswith((".brp", ".brep")) else d),
        f"{f}: a whole zip without its shape files (*.brp)")
    return files


PROBE = """
import sys, FreeCAD
path = sys.argv[-1]
try:
    if path.lower().endswith('.fcstd'):
        doc = FreeCAD.openDocument(path)
        faces = sum(len(o.Shape.Faces) for o in doc.Objects if hasattr(o, 'Shape'))
    else:
        import Part
        faces = len(Part.read(path).Faces)
    print('PROBE read, %d faces' % faces)
except Exception as exc:
    print('PROBE %s: %s' % (type(exc).__name__, str(exc).strip().splitlines()[0][:160]
                            if str(exc).strip() else ''))
"""


def describe(proc: subprocess.CompletedProcess) -> str:
    """How the reader's process ended: the Python answer, or the signal and OCCT's innermost
    frame of FreeCAD's backtrace, or the exit status and the last line it printed."""
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("PROBE ")]
    err = [re.sub(r"\x1b\[[0-9;]*m", "", ln).strip() for ln in proc.stderr.splitlines()]
    err = [ln for ln in err if ln]
    frames = [m.group(1) for ln in err if (m := re.match(r"#\d+\s+\S+ in (\S+?)\(", ln))]
    where = f" in {frames[0]}" if frames else ""
    if proc.returncode < 0 or proc.returncode >= 128:
        number = -proc.returncode if proc.returncode < 0 else proc.returncode - 128
        return f"crash: {signal.Signals(number).name}{where} (exit {proc.returncode})"
    caught = [m.group(1) for ln in err if (m := re.search(r"received signal (SIG\w+)", ln))]
    if caught:
        return (f"crash: {caught[0]}{where} (FreeCAD's handler prints the backtrace, exit "
                f"{proc.returncode})")
    if lines:
        text = lines[-1][len("PROBE "):]
        return text if proc.returncode == 0 else f"exit {proc.returncode}; {text}"
    last = err[-1] if err else "nothing"
    return f"exit {proc.returncode} with no Python answer; last printed: {last}"


def probe(freecadcmd: list[str]) -> list[tuple[str, str, str, str]]:
    """(file, what, FreeCAD 0.20's reader, bin/bsplinecam check) for every damaged file."""
    rows = []
    script = OUT / ".probe.py"
    script.write_text(PROBE)
    try:
        for name, (_, what) in damaged().items():
            path = OUT / name
            try:
                proc = subprocess.run([*freecadcmd, str(script), str(path)], capture_output=True,
                                      text=True, timeout=300, check=False,
                                      stdin=subprocess.DEVNULL)
                fc = describe(proc)
            except subprocess.TimeoutExpired:
                fc = "no end within 300 s"
            try:
                cli = subprocess.run([str(ROOT / "bin" / "bsplinecam"), "check",
                                      str(path.relative_to(ROOT))], capture_output=True,
                                     text=True, timeout=300, check=False, cwd=ROOT,
                                     stdin=subprocess.DEVNULL)
                last = [ln for ln in cli.stderr.splitlines() if ln.strip()]
                if cli.returncode < 0:
                    verdict = f"killed by {signal.Signals(-cli.returncode).name}"
                else:
                    verdict = f"exit {cli.returncode}"
                if cli.returncode != 0 and last:
                    verdict += f": {last[-1].strip()[:200]}"
            except subprocess.TimeoutExpired:
                verdict = "no end within 300 s"
            rows.append((name, what, fc, verdict))
            print(f"{name}: {fc} | {verdict}", file=sys.stderr)
    finally:
        script.unlink()
    return rows


def readme(rows: list[tuple[str, str, str, str]], freecad: str) -> str:
    head = f"""# Damaged parts

Made by `python3 tools/make_damaged_parts.py` (deterministic: a fixed seed and fixed zip dates)
from three corpus files of tests/parts/ ({STEP_SOURCE.name}, {BREP_SOURCE.name},
{FCSTD_SOURCE.name}; their sources and licences are in ../README.md).  The readers' tests run
every file here (`tests/parts/damaged/*`): each must end in a clean refusal (or a
clean read where FreeCAD recovers the file), never a crash.

"What FreeCAD does" is `Part.read(FILE)` (STEP, BREP) or `FreeCAD.openDocument(FILE)` (FCStd)
in a fresh `freecadcmd` ({freecad}), one process per file; "bsplinecam check" is
`bin/bsplinecam check FILE` at the time the table was made.  Regenerate the files and this table
with `python3 tools/make_damaged_parts.py --probe`.

| file | what was done | what FreeCAD does | bsplinecam check |
|---|---|---|---|
"""
    body = "".join(f"| {n} | {w} | {fc} | {cli.replace('|', '/')} |\n" for n, w, fc, cli in rows)
    return head + body


def freecad_version(freecadcmd: list[str]) -> str:
    proc = subprocess.run([*freecadcmd, "-c", "import FreeCAD; print('V', *FreeCAD.Version()[:3])"],
                          capture_output=True, text=True, timeout=120, check=False)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("V ")]
    return "FreeCAD " + ".".join(lines[-1].split()[1:4]) if lines else "?"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--probe", action="store_true",
                        help="read each file with FreeCAD and write damaged/README.md")
    parser.add_argument("--freecadcmd", default=os.environ.get("BSPLINECAM_FREECADCMD",
                                                               "freecadcmd"))
    args = parser.parse_args(argv)
    OUT.mkdir(parents=True, exist_ok=True)
    files = damaged()
    for name, (data, _) in files.items():
        (OUT / name).write_bytes(data)
    total = sum(len(d) for d, _ in files.values())
    print(f"{len(files)} files, {total} bytes in {OUT.relative_to(ROOT)}", file=sys.stderr)
    if args.probe:
        cmd = args.freecadcmd.split()
        rows = probe(cmd)
        (OUT / "README.md").write_text(readme(rows, freecad_version(cmd)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
