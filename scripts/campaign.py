#!/usr/bin/env python3
"""A mutation campaign through the program itself (issue 22, item 5).

libFuzzer (scripts/fuzz.sh) tries the readers' parsers on bytes; this runs mutated .bt, .ot,
.graph files and TUM RGB-D folders through `octovk` as a user would, each in a fresh directory
under `ulimit -v` and a timeout, and classifies each run:
  accepted    exit 0, and every output exists
  error       exit 1 or 2, one stderr line 'octovk: error: ...', outputs as before, nothing new
  crash       killed by a signal, or another exit code
  hang        over --timeout twice in a row (once may be a loaded machine), the group killed
  multiline   an error that is not exactly one 'octovk: error: ' line
  unexpected  'octovk: error: unexpected failure: ...': an exception octovk did not expect (under
              the address-space limit usually std::bad_alloc: memory not bounded by the input)
  changed     a failed run that altered an existing output or left a new one behind
  no-output   exit 0 without every output written
  leftover    any other file left in the directory (a temporary .NAME.octovk.tmp-*)
  escaped     a TUM folder accepted although depth.txt names an image outside it (absolute, '..')
Every class but accepted and error fails the campaign; each such mutant is saved with a
script that reproduces it. Deterministic from --seed: mutant I of format F is the same every time.
Usage: scripts/campaign.py [--budget-seconds S] [--count N] [--seed N] [--formats bt,ot,graph,tum]
"""
import argparse, math, os, random, resource, shlex, shutil, signal, struct, subprocess, sys
import tempfile, threading, time, zlib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CORPUS = ROOT / "tests" / "fuzz" / "corpus"
FORMATS = ["bt", "ot", "graph", "tum"]
BAD = ["crash", "hang", "multiline", "unexpected", "changed", "no-output", "leftover", "escaped",
       "script-bug"]
U32 = [0, 1, 2, 3, 4, 0x7F, 0x80, 0xFF, 0xFFFF, 0x10000, 0x10000000, 0x7FFFFFFF, 0x80000000,
       0xFFFFFFFF]
DOUBLES = [math.nan, math.inf, -math.inf, 0.0, -0.0, 5e-324, 1e-30, 1e6, -1e6, 3276.7, 1e30,
           1e308, -1e308]
NUMBERS = ["0", "-1", "1", "nan", "inf", "-inf", "1e-300", "1e300", "1e39", "99999999999999999999",
           "4294967296", "0x10", "1,5", "", "abc", "0.1", "65536", "-0.0"]
# Image names: outside the folder (must be refused), not a file, odd bytes, very long.
NAMES = ["/dev/zero", "/etc/passwd", "../outside.png", "depth/../../outside.png", "depth",
         "depth/missing.png", "depth.txt", "a b.png", ".", "depth//a.png", "x" * 5000,
         "depth/fifo.png", "depth/link.png", "depth/a.png\x00x", "\xff\xfe.png", "-o"]


# ---- seeds: small, so that a run takes well under a second on lavapipe ----

def png_chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def depth_png(width, height, depths):  # 16-bit grayscale, what a TUM folder holds
    rows = b"".join(b"\0" + b"".join(struct.pack(">H", depths[(y * width + x) % len(depths)])
                                      for x in range(width)) for y in range(height))
    ihdr = struct.pack(">IIBBBBB", width, height, 16, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", ihdr) +
            png_chunk(b"IDAT", zlib.compress(rows)) + png_chunk(b"IEND", b""))


def graph(scans):  # OctoMap's ScanGraph::writeBinary: [(points, (tx ty tz), (qw qx qy qz))]
    out = struct.pack("<I", len(scans))
    for i, (points, t, q) in enumerate(scans):
        out += struct.pack("<I", len(points))
        for p in points:
            out += struct.pack("<I3d", 3, *p)
        out += struct.pack("<I3dI4dI", 3, *t, 4, *q, i)
    return out + struct.pack("<I", 0)


def tum_folder(times, poses, images):  # {relative path: bytes}
    files = {"depth.txt": "# depth maps\n# timestamp filename\n" +
             "".join(f"{t:.6f} depth/{t:.6f}.png\n" for t in times),
             "groundtruth.txt": "# timestamp tx ty tz qx qy qz qw\n" +
             "".join(f"{t:.4f} {p}\n" for t, p in zip(times, poses))}
    files = {k: v.encode() for k, v in files.items()}
    files.update({f"depth/{t:.6f}.png": img for t, img in zip(times, images)})
    return files


def make_seeds(octovk, work):
    small = graph([([(1.0, y * 0.1, 0.2 + 0.1 * y) for y in range(6)] + [(math.nan, 0, 0)],
                    (0, 0, 0), (1, 0, 0, 0)),
                   ([(0.5, -0.3, z * 0.2) for z in range(5)], (0.2, 0.1, 0.3),
                    (0.7071, 0, 0, 0.7071))])
    # A graph without scans is refused (nothing to integrate), so it cannot be a seed that must
    # be accepted; the fuzzer's corpus keeps it.
    seeds = {"graph": [small] + [p.read_bytes() for p in sorted((CORPUS / "graph").glob("*"))
                                 if p.read_bytes()[:4] != b"\0\0\0\0"]}
    (work / "seed.graph").write_bytes(small)  # maps written by the program itself, too
    subprocess.run([octovk, "integrate", "seed.graph", "-o", "seed.bt", "-o", "seed.ot", "-q"],
                   cwd=work, check=True, stdout=subprocess.DEVNULL)
    for fmt in ("bt", "ot"):
        seeds[fmt] = [(work / f"seed.{fmt}").read_bytes()] + [
            p.read_bytes() for p in sorted((CORPUS / fmt).glob("*"))]
    images = [depth_png(8, 6, [5000 + 97 * i for i in range(48)]), depth_png(4, 3, [0, 7000]),
              (CORPUS / "depth_png" / "gray16_3x2.png").read_bytes(),
              (CORPUS / "depth_png" / "gray16_adam7_5x4.png").read_bytes()]
    times = [1305031102.1758 + 0.1 * k for k in range(3)]
    poses = ["0 0 0 0 0 0 1", "0.1 0 0.05 0 0.0998 0 0.9950", "0.2 0.1 0 0.7071 0 0 0.7071"]
    seeds["tum"] = [tum_folder(times, poses, images), tum_folder(times[:1], poses[:1], images[3:])]
    for lists in sorted((CORPUS / "tum_lists").glob("*")):  # TUM's layout: comments, CRLF
        gt, depth = lists.read_bytes().split(b"\0", 1)
        folder = {"groundtruth.txt": gt, "depth.txt": depth}
        for i, line in enumerate(depth.splitlines()):
            if line.strip() and not line.startswith(b"#"):
                folder[line.split()[1].decode()] = images[i % 2]
        seeds["tum"].append(folder)
    extra_pngs = [p.read_bytes() for p in sorted((CORPUS / "depth_png").glob("*"))]
    return seeds, images + extra_pngs


# ---- mutators: each takes a random.Random and bytes, returns bytes ----

def flip_bits(r, b):
    b = bytearray(b)
    for _ in range(r.randint(1, 8)):
        if b:
            b[r.randrange(len(b))] ^= 1 << r.randrange(8)
    return bytes(b)


def overwrite(r, b):  # an interesting byte, u32 (either byte order) or double, anywhere
    value = r.choice([bytes([r.choice([0, 1, 0x7F, 0x80, 0xFF])]),
                      struct.pack(r.choice("<>") + "I", r.choice(U32)),
                      struct.pack("<d", r.choice(DOUBLES))])
    at = r.randrange(max(1, len(b)))
    return b[:at] + value + b[at + len(value):]


def truncate(r, b):
    return b[:r.randrange(len(b) + 1)]


def chunk(r, b):  # duplicate, delete or insert random bytes at a random place
    i, j = sorted(r.randrange(len(b) + 1) for _ in range(2))
    at = r.randrange(len(b) + 1)
    what = r.randrange(3)
    if what == 0:
        return b[:at] + b[i:j] + b[at:]
    if what == 1:
        return b[:i] + b[j:]
    return b[:at] + bytes(r.randrange(256) for _ in range(r.randint(1, 16))) + b[at:]


def edit_line(r, b, keys=None, tokens=NUMBERS, field=None):  # text: one field or a whole line
    lines = b.split(b"\n")
    picks = [i for i, l in enumerate(lines) if (keys is None and l.strip() and l[:1] != b"#")
             or (keys is not None and l.split(b" ")[0] in keys)]
    if not picks:
        return chunk(r, b)
    i = r.choice(picks)
    fields = lines[i].split(b" ")
    what = r.randrange(5)
    if what == 0:
        del lines[i]
    elif what == 1:
        lines.insert(i, lines[i])
    elif what == 2:
        lines[i] += r.choice([b"\r", b" 1", b"\0", b" # x", b"\t"])
    else:
        k = field if field is not None else r.randrange(len(fields)) if len(fields) < 2 \
            else r.randrange(1 if keys else 0, len(fields))
        fields[min(k, len(fields) - 1)] = r.choice(tokens).encode("utf-8", "surrogateescape")
        lines[i] = b" ".join(fields)
    return b"\n".join(lines)


def tree_header(r, b):  # .bt/.ot: the text header OctoMap reads before the node data
    head, sep, data = b.partition(b"\ndata\n")
    if r.random() < 0.2:
        return r.choice([b"# Octomap OcTree file", b"# Octomap OcTree binary file", b""]) + \
            head[head.find(b"\n"):] + r.choice([sep, b"\ndata", b"\nDATA\n"]) + data
    tokens = NUMBERS + ["OcTree", "ColorOcTree", "OcTreeStamped", "CountingOcTree", "48", "49"]
    return edit_line(r, head, {b"id", b"res", b"size"}, tokens) + sep + data


def graph_fields(r, b):  # .graph: a count (scans, points, edges) or a coordinate of a scan
    counts, doubles, at = [], [], 0
    try:
        n, = struct.unpack_from("<I", b, 0)
        counts.append(0)
        at = 4
        for _ in range(n):
            points, = struct.unpack_from("<I", b, at)
            counts.append(at)
            if at + 4 + 28 * points > len(b):
                break
            doubles += [at + 8 + 28 * p + 8 * k for p in range(points) for k in range(3)]
            at += 4 + 28 * points
            doubles += [at + 4 + 8 * k for k in range(3)] + [at + 32 + 8 * k for k in range(4)]
            at += 68
        counts.append(at)
    except struct.error:
        pass
    if doubles and r.random() < 0.5:
        at = r.choice(doubles)
        return b[:at] + struct.pack("<d", r.choice(DOUBLES)) + b[at + 8:]
    if not counts:
        return overwrite(r, b)
    at = r.choice(counts)
    old, = struct.unpack_from("<I", b + bytes(at + 4), at)
    value = r.choice(U32 + [old + 1, max(old - 1, 0)]) & 0xFFFFFFFF
    return b[:at] + struct.pack("<I", value) + b[at + 4:]


def png_fields(r, b, fix_only=False):  # PNG chunks, checksums fixed so that libpng reads on
    chunks, at = [], 8
    while at + 12 <= len(b):
        n, = struct.unpack_from(">I", b, at)
        chunks.append([b[at + 4:at + 8], b[at + 8:at + 8 + n]])
        at += 12 + n
    if fix_only or not chunks or chunks[0][0] != b"IHDR" or len(chunks[0][1]) != 13:
        return b[:8] + b"".join(png_chunk(k, d) for k, d in chunks) + b[at:] if fix_only \
            else overwrite(r, b)
    what = r.randrange(5)
    ihdr = bytearray(chunks[0][1])
    if what == 0:  # width, height, bit depth, colour type, interlace
        k = r.choice([0, 4])
        ihdr[k:k + 4] = struct.pack(">I", r.choice(U32 + [65536, 65537, 100000]))
    elif what == 1:
        ihdr[r.randrange(8, 13)] = r.choice([0, 1, 2, 3, 4, 6, 8, 16, 255])
    elif what == 2:  # a chunk announcing far more bytes than the file holds
        kind = r.choice([b"tEXt", b"zTXt", b"iCCP", b"IDAT", b"tRNS", b"eXIf"])
        raw = struct.pack(">I", r.choice([0x7FFFFFFF, 0x10000000, 0xFFFFFF])) + kind + b"x" * 9
        return b[:33] + raw + b[33:]
    elif what == 3:  # image data that inflates to far more (or less) than the header says
        rows = bytes(r.choice([1, 100, 10000, 2000000]))
        chunks = [c for c in chunks if c[0] != b"IDAT"]
        chunks.insert(1, [b"IDAT", zlib.compress(rows, 9)])
    else:  # a chunk repeated or dropped
        i = r.randrange(len(chunks))
        chunks[i:i + 1] = [] if r.random() < 0.5 else [chunks[i], chunks[i]]
    if chunks and chunks[0][0] == b"IHDR":
        chunks[0][1] = bytes(ihdr)
    return b"\x89PNG\r\n\x1a\n" + b"".join(png_chunk(k, d) for k, d in chunks) + b[at:]


GENERIC = [flip_bits, overwrite, truncate, chunk]


def mutate_tum(r, folder, pngs):
    folder = dict(folder)
    images = [k for k, v in folder.items() if k.endswith(".png") and isinstance(v, bytes)]
    what = r.randrange(7)
    lists = [k for k in ("depth.txt", "groundtruth.txt") if isinstance(folder.get(k), bytes)]
    if what <= 1 and lists:  # a list's fields: names, timestamps, pose values
        name = r.choice(lists)
        names = name == "depth.txt" and r.random() < 0.5
        folder[name] = edit_line(r, folder[name], None, NAMES if names else NUMBERS,
                                 1 if names else None)
    elif what == 2 and lists:
        name = r.choice(lists)
        folder[name] = r.choice(GENERIC)(r, folder[name])
    elif what <= 4 and images:  # an image's bytes or PNG fields
        k = r.choice(images)
        folder[k] = r.choice(GENERIC + [png_fields] * 3)(r, folder[k])
        if r.random() < 0.5:
            folder[k] = png_fields(r, folder[k], fix_only=True)
    elif what == 5 and images:  # another image (8-bit, 2 GiB text chunk), a FIFO, a link out
        folder[r.choice(images)] = r.choice(pngs + ["fifo", "link", "dir"])
    else:
        del folder[r.choice(list(folder))]
    folder.setdefault("depth/fifo.png", "fifo")  # named by NAMES: a FIFO must not hang a read
    folder.setdefault("depth/link.png", "link")
    return folder


def make_mutant(seed, fmt, index, seeds, pngs):
    r = random.Random(f"{seed}/{fmt}/{index}")
    mutant = r.choice(seeds[fmt])
    for _ in range(r.choice([1, 1, 1, 2, 3])):
        if fmt == "tum":
            mutant = mutate_tum(r, mutant, pngs)
        else:
            special = {"bt": tree_header, "ot": tree_header, "graph": graph_fields}[fmt]
            mutant = r.choice(GENERIC + [special] * 2)(r, mutant)
    return r, mutant


# ---- running a mutant ----

def materialize(d, fmt, mutant):  # writes the inputs; returns what the run may not touch
    if fmt == "tum":  # what '..', absolute names and links out of the folder would reach
        (d / "outside.png").write_bytes(depth_png(2, 2, [6000]))
    entries = mutant.items() if fmt == "tum" else [(f"M.{fmt}", mutant)]
    for name, content in entries:
        path = d / "in" / name if fmt == "tum" else d / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if content == "fifo":
            os.mkfifo(path)
        elif content == "link":
            path.symlink_to("../../outside.png")
        elif content == "dir":
            path.mkdir()
        else:
            path.write_bytes(content)
    return {str(p.relative_to(d)) for p in d.rglob("*")}


def command(fmt, r):  # (arguments, outputs); an existing out.* must survive a failed run
    integrate = ["-q", "--max-device-memory", "512M"]
    if fmt == "graph":
        return ["integrate", "M.graph", "-o", "out.bt", "-o", "out.ot"] + integrate, \
            ["out.bt", "out.ot"]
    if fmt == "tum":
        return ["integrate", "in", "-o", "out.bt"] + integrate, ["out.bt"]
    return r.choice([(["info", f"M.{fmt}"], []),
                     (["export", f"M.{fmt}", "-o", "out.ply", "--max-device-memory", "512M"],
                      ["out.ply"]),
                     (["render", f"M.{fmt}", "-o", "out.png", "--size", "16x12"], ["out.png"]),
                     (["distance", f"M.{fmt}", "--box", "-1", "-1", "-1", "1", "1", "1", "-o",
                       "out.png", "--max-device-memory", "512M"], ["out.png"])])


def execute(argv, cwd, timeout):
    p = subprocess.Popen(argv, cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, start_new_session=True)
    try:
        out, err = p.communicate(timeout=timeout)
        return p.returncode, out, err
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)  # the whole group: nothing may outlive its run
        out, err = p.communicate()
        return None, out, err


def names_outside(depth_txt):  # depth.txt's data lines as octovk splits them (splitDataLines)
    for line in depth_txt.split(b"\n"):
        fields = [f for f in line.removesuffix(b"\r").replace(b"\t", b" ").split(b" ") if f]
        if len(fields) == 2 and fields[0][:1] != b"#" and (
                fields[1].startswith(b"/") or b".." in fields[1].split(b"/")):
            yield fields[1]


def classify(rc, err, d, inputs, outputs, before):
    if rc is None:
        return "hang", "over the timeout"
    if rc < 0 or rc not in (0, 1, 2):
        return "crash", f"signal {-rc}" if rc < 0 else f"exit {rc}"
    if rc != 0:
        if not (err.startswith(b"octovk: error: ") and err.count(b"\n") == 1
                and err.endswith(b"\n") and b"\r" not in err):
            return "multiline", f"exit {rc}, stderr {err[:300]!r}"
        if err.startswith(b"octovk: error: unexpected failure"):
            return "unexpected", err.decode(errors="replace").strip()
        for name in outputs:
            now = (d / name).read_bytes() if (d / name).is_file() else None
            if now != before.get(name):
                return "changed", f"{name} changed or created by a failed run"
    elif not all((d / name).is_file() and (d / name).read_bytes() != before.get(name)
                 for name in outputs):
        return "no-output", "exit 0, an output not written"
    depth_txt = d / "in" / "depth.txt"
    if rc == 0 and depth_txt.is_file() and any(names_outside(depth_txt.read_bytes())):
        return "escaped", f"accepted, depth.txt names {next(names_outside(depth_txt.read_bytes()))}"
    extra = sorted({str(p.relative_to(d)) for p in d.rglob("*")} - inputs - set(outputs))
    if extra:
        return "leftover", "left " + ", ".join(extra)
    return ("accepted", "") if rc == 0 else ("error", "")


def run_case(args, fmt, index, work):
    r, mutant = make_mutant(args.seed, fmt, index, SEEDS, PNGS)
    argv, outputs = command(fmt, r)
    # The first output exists before the run and must survive a failed run byte for byte; the
    # others (out.ot of a graph) must not appear.
    before = {name: b"an existing file, which a failed run must leave as it was\n"
              for name in outputs[:1]}
    for attempt in range(2):  # a timeout counts only if it happens again
        d = Path(tempfile.mkdtemp(prefix=f"{fmt}-{index}-", dir=work))
        try:
            inputs = materialize(d, fmt, mutant) | set(before)
            for name, content in before.items():
                (d / name).write_bytes(content)
            rc, out, err = execute([args.octovk] + argv, d, args.timeout)
            cls, why = classify(rc, err, d, inputs, outputs, before)
        finally:
            shutil.rmtree(d, ignore_errors=True)
        if cls != "hang":
            break
    if cls in BAD:
        save(args, fmt, index, mutant, argv, before, cls, why, rc, out, err)
    return cls


# ---- attacks: fixed hostile situations, each run once (format "attack") ----
# Each returns (class, why) with the classes above; a situation octovk must handle is built
# around a seed, the run is classified as a mutant's, then the attack checks what it is about.

SPARSE_GIB = 3


def sparse(path, head, gib):  # `head`, then zeros to `gib` GiB that take no disk space
    path.write_bytes(head)
    os.truncate(path, gib << 30)


def run_in(d, args, argv, outputs, before=None, shell_prefix=None):
    before = before or {}
    for name, content in before.items():
        (d / name).write_bytes(content)
    inputs = {str(p.relative_to(d)) for p in d.rglob("*")}
    full = [args.octovk] + argv
    if shell_prefix:  # e.g. 'ulimit -f 64': a limit for this run only, set by its own shell
        full = ["sh", "-c", f"{shell_prefix}; exec {shlex.join(full)}"]
    t0 = time.monotonic()
    rc, out, err = execute(full, d, args.timeout)
    cls, why = classify(rc, err, d, inputs, outputs, before)
    return cls, why, rc, err, time.monotonic() - t0


def attack_sparse_files(args, d):  # read whole before checked: 3.2 GB of RSS for 4 KB on disk
    sparse(d / "big.bt", SEEDS["bt"][0], SPARSE_GIB)
    sparse(d / "big.graph", SEEDS["graph"][0][:-4], SPARSE_GIB)
    tum = d / "in"
    for name, content in SEEDS["tum"][0].items():
        (tum / name).parent.mkdir(parents=True, exist_ok=True)
        (tum / name).write_bytes(content)
    sparse(tum / "depth.txt", SEEDS["tum"][0]["depth.txt"], 10)
    for argv, outputs in ((["info", "big.bt"], []), (["integrate", "big.graph", "-o", "o.bt"], ["o.bt"]),
                          (["integrate", "in", "-o", "o.bt", "-q"], ["o.bt"])):
        cls, why, rc, err, secs = run_in(d, args, argv, outputs)
        if cls == "accepted":
            return "changed", f"{argv}: a {SPARSE_GIB} GiB file of zeros was accepted"
        if cls != "error":
            return cls, f"{argv}: {why}"
        if secs > 5:
            return "hang", f"{argv}: {secs:.1f} s to refuse a file of zeros (read whole first)"
    return "error", ""


def attack_huge_png(args, d):  # a 16000 x 16000 header: decoded whole before the size check
    ihdr = struct.pack(">IIBBBBB", 16000, 16000, 16, 0, 0, 0, 0)
    rows, row = zlib.compressobj(9), b"\0" * (16000 * 2 + 1) * 500
    data = b"".join(rows.compress(row) for _ in range(32)) + rows.flush()  # whole: 500 KB
    png = (b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", ihdr) + png_chunk(b"IDAT", data) +
           png_chunk(b"IEND", b""))
    folder = dict(SEEDS["tum"][1])
    for name in list(folder):
        if name.endswith(".png"):
            folder[name] = png
    for name, content in folder.items():
        (d / "in" / name).parent.mkdir(parents=True, exist_ok=True)
        (d / "in" / name).write_bytes(content)
    for argv, outputs in ((["integrate", "in", "-o", "o.bt", "-q"], ["o.bt"]),
                          (["convert", "in", "-o", "o.graph"], ["o.graph"])):
        cls, why, rc, err, secs = run_in(d, args, argv, outputs)
        if cls not in ("error", "accepted"):
            return cls, f"{argv}: {why}"
        if secs > 5:
            return "hang", f"{argv}: {secs:.1f} s on a 16000 x 16000 PNG (decoded before checked)"
    return "error", ""


def attack_file_size_limit(args, d):  # SIGXFSZ killed the run and left its temporary
    (d / "M.graph").write_bytes(SEEDS["graph"][0])
    cls, why, rc, err, _ = run_in(d, args, ["integrate", "M.graph", "-o", "out.ot", "-q"],
                                  ["out.ot"], before={"out.ot": b"kept\n"},
                                  shell_prefix="ulimit -f 1")
    if cls == "accepted" and (d / "out.ot").stat().st_size > 1024:
        return "changed", "a file over ulimit -f was written"
    return cls, why


def attack_long_names(args, d):  # names of 235-255 bytes: the temporary's name was too long
    (d / "M.graph").write_bytes(SEEDS["graph"][0])
    name = "m" * 250 + ".bt"
    cls, why = run_in(d, args, ["integrate", "M.graph", "-o", name, "-q"], [name])[:2]
    return ("no-output", f"a valid name of {len(name)} bytes was refused") if cls == "error" else \
        (cls, why)


def attack_output_links(args, d):  # a link was replaced by a file, a 0444 file became 0644
    (d / "M.graph").write_bytes(SEEDS["graph"][0])
    (d / "target.bt").write_bytes(b"old\n")
    (d / "link.bt").symlink_to("target.bt")
    (d / "ro.bt").write_bytes(b"old\n")
    os.chmod(d / "ro.bt", 0o444)
    rc, out, err = execute([args.octovk, "integrate", "M.graph", "-o", "link.bt", "-o", "ro.bt",
                            "-q"], d, args.timeout)
    if rc not in (0, 1):
        return ("hang", "over the timeout") if rc is None else ("crash", f"exit {rc}")
    if rc == 0:
        if not (d / "link.bt").is_symlink():
            return "changed", "writing through a symbolic link replaced the link"
        if (d / "target.bt").read_bytes() == b"old\n":
            return "no-output", "the link's target was not written"
        if os.stat(d / "ro.bt").st_mode & 0o777 != 0o444:
            return "changed", f"a 0444 output became {os.stat(d / 'ro.bt').st_mode & 0o777:o}"
        return "accepted", ""
    return classify(rc, err, d, {str(p.relative_to(d)) for p in d.rglob("*")}, [], {})


def resolution_of(path):  # the 'res' line of a .bt / .ot header
    for line in path.read_bytes().split(b"\n")[:8]:
        if line.startswith(b"res "):
            return float(line[4:])
    return None


def attack_one_output_set(args, d):  # concurrent runs on one -o set ended up mixed
    (d / "M.graph").write_bytes(SEEDS["graph"][0])
    for trial in range(4):
        procs = [subprocess.Popen([args.octovk, "integrate", "M.graph", "-o", "s.bt", "-o", "s.ot",
                                   "-q", "--resolution", res], cwd=d, stdin=subprocess.DEVNULL,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
                 for res in ("0.1", "0.2", "0.3")]
        for p in procs:
            try:
                p.communicate(timeout=args.timeout)
            except subprocess.TimeoutExpired:
                p.kill()
                return "hang", "a run on a shared output set"
            if p.returncode not in (0, 1):
                return "crash", f"exit {p.returncode} of a run on a shared output set"
        bt, ot = resolution_of(d / "s.bt"), resolution_of(d / "s.ot")
        if bt is None or bt != ot:
            return "changed", f"trial {trial}: the set is mixed: .bt res {bt}, .ot res {ot}"
    extra = sorted(p.name for p in d.iterdir()) 
    if any(n not in ("M.graph", "s.bt", "s.ot") for n in extra):
        return "leftover", "left " + ", ".join(extra)
    return "accepted", ""


PY_NEW = """
import octovk, numpy as np
for name in dir(octovk):
    cls = getattr(octovk, name)
    if not isinstance(cls, type) or not hasattr(cls, "__new__") or name.startswith("_"):
        continue
    try:
        obj = cls.__new__(cls)
    except TypeError:
        continue
    for attr in dir(obj):
        if attr.startswith("__"):
            continue
        for call_args in ((), (np.zeros((2, 3), np.float32),), ("x.bt",)):
            try:
                value = getattr(obj, attr)
                if callable(value):
                    value(*call_args)
            except Exception:
                pass
    for use in (lambda: octovk.Map(context=obj), lambda: octovk.Map(obj)):
        try:
            use()
        except Exception:
            pass
print("done")
"""

PY_BATCH = """
import octovk, numpy as np
m = octovk.Map(resolution=0.1)
m.insert_point_cloud(np.random.default_rng(1).uniform(-2, 2, (1000, 3)).astype(np.float32),
                     np.zeros(3, np.float32))
big = np.zeros((9_000_000, 3), np.float32)  # beyond one binding of results on lavapipe
try:
    assert len(m.search(big)[0]) == len(big)
except octovk.Error:
    pass
assert len(m.search(big[:10])[0]) == 10, "the map stopped working after a large batch"
print("done")
"""


def attack_python(args, d):  # __new__ objects crashed the interpreter; a batch broke the map
    module = Path(args.octovk).resolve().parent / "python"
    if not any(module.glob("octovk*.so")):
        return "error", ""  # built without the Python module: nothing to attack
    env = dict(os.environ, PYTHONPATH=str(module), PYTHONDONTWRITEBYTECODE="1")
    for what, code in (("__new__ objects", PY_NEW), ("a batch beyond one binding", PY_BATCH)):
        p = subprocess.run(["/usr/bin/python3", "-c", code], cwd=d, env=env, capture_output=True,
                           timeout=args.timeout * 4)
        if p.returncode < 0:
            return "crash", f"python, {what}: signal {-p.returncode}"
        if p.returncode != 0 or not p.stdout.strip().endswith(b"done"):
            return "unexpected", f"python, {what}: {p.stderr.decode(errors='replace')[-300:]}"
    return "accepted", ""


ATTACKS = [attack_sparse_files, attack_huge_png, attack_file_size_limit, attack_long_names,
           attack_output_links, attack_one_output_set, attack_python]


def run_attacks(args, work, counts):
    for attack in ATTACKS:
        d = Path(tempfile.mkdtemp(prefix=attack.__name__ + "-", dir=work))
        try:
            cls, why = attack(args, d)
        except Exception as e:  # a bug of the campaign fails it too, never passes
            cls, why = "script-bug", repr(e)
        finally:
            shutil.rmtree(d, ignore_errors=True)
        counts[cls] = counts.get(cls, 0) + 1
        if cls in BAD:
            print(f"campaign: {cls.upper()}: {attack.__name__}: {why}", file=sys.stderr, flush=True)


def save(args, fmt, index, mutant, argv, before, cls, why, rc, out, err):
    d = Path(args.save) / f"{fmt}-{index}-{cls}"
    shutil.rmtree(d, ignore_errors=True)
    d.mkdir(parents=True)
    materialize(d, fmt, mutant)
    for name, content in before.items():
        (d / name).write_bytes(content)
    line = (f"cd {shlex.quote(str(d.resolve()))} && (ulimit -v {args.ulimit_mb * 1024}; "
            f"LP_NUM_THREADS=0 timeout {args.timeout} {shlex.join([args.octovk] + argv)})")
    (d / "result.txt").write_text(f"{cls}: {why}\nexit: {rc}\nrun: {line}\n"
                                  f"stdout:\n{out.decode(errors='replace')}\n"
                                  f"stderr:\n{err.decode(errors='replace')}\n")
    print(f"campaign: {cls.upper()}: {fmt} mutant {index}: {why}\n  saved in {d}\n  reproduce: "
          f"{line}", file=sys.stderr, flush=True)


def main():
    global SEEDS, PNGS
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--octovk", default=str(ROOT / "build" / "octovk"))
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--budget-seconds", type=float, default=120, help="all formats together")
    p.add_argument("--count", type=int, default=0, help="mutants per format (0: until budget)")
    p.add_argument("--formats", default=",".join(FORMATS))
    p.add_argument("--timeout", type=float, default=30, help="seconds a run may take")
    p.add_argument("--ulimit-mb", type=int, default=2048, help="address space of a run, MiB")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    p.add_argument("--save", default=str(ROOT / "build" / "campaign-failures"))
    p.add_argument("--no-attacks", action="store_true", help="mutants only")
    args = p.parse_args()
    formats = [f for f in args.formats.split(",") if f]
    if not os.access(args.octovk, os.X_OK) or any(f not in FORMATS for f in formats):
        p.error(f"need an executable --octovk ({args.octovk}) and formats from {FORMATS}")
    # One process per core, each lavapipe without worker threads (the help: faster on small scans).
    os.environ.setdefault("LP_NUM_THREADS", "0")
    start = time.monotonic()
    work = Path(tempfile.mkdtemp(prefix="octovk-campaign-"))
    try:
        SEEDS, PNGS = make_seeds(args.octovk, work)
        # The limit is set here, after the seeds, and inherited by every run: setrlimit in a
        # preexec_fn is not safe in a process with threads. 2 GiB: lavapipe maps a few hundred MB
        # of address space; a run of a tiny input reaching 2 GiB is unbounded allocation.
        limit = args.ulimit_mb << 20
        resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))
        # The unmutated seeds first: each must be accepted, or the limits are wrong, not octovk.
        for fmt in formats:
            for k, seed in enumerate(SEEDS[fmt]):
                d = Path(tempfile.mkdtemp(dir=work))
                inputs = materialize(d, fmt, seed)
                argv, outputs = command(fmt, random.Random(k))
                rc, out, err = execute([args.octovk] + argv, d, args.timeout)
                cls, why = classify(rc, err, d, inputs, outputs, {})
                if cls != "accepted":
                    sys.exit(f"campaign: error: seed {k} of {fmt} is not accepted ({cls}: {why}; "
                             f"{err.decode(errors='replace').strip()}): the campaign is broken")
        counts = {f: {} for f in formats}
        if not args.no_attacks:
            counts["attack"] = {}
            run_attacks(args, work, counts["attack"])
        deadline = start + args.budget_seconds
        order = ((fmt, i) for i in range(args.count or 1 << 40) for fmt in formats)
        lock = threading.Lock()

        def worker():
            while True:
                with lock:
                    task = next(order, None) if time.monotonic() < deadline else None
                if task is None:
                    return
                try:
                    cls = run_case(args, task[0], task[1], work)
                except Exception as e:  # a bug of the campaign fails it too, never passes
                    print(f"campaign: error: {task}: {e!r}", file=sys.stderr)
                    cls = "script-bug"
                with lock:
                    counts[task[0]][cls] = counts[task[0]].get(cls, 0) + 1

        threads = [threading.Thread(target=worker) for _ in range(args.jobs)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        shutil.rmtree(work, ignore_errors=True)
    classes = ["accepted", "error"] + BAD
    print(f"campaign: seed {args.seed}, {time.monotonic() - start:.0f} s, {args.jobs} jobs, "
          f"ulimit -v {args.ulimit_mb} MiB, timeout {args.timeout:g} s")
    print(f"{'format':<8}{'runs':>7}" + "".join(f"{c:>11}" for c in classes))
    for fmt in counts:
        print(f"{fmt:<8}{sum(counts[fmt].values()):>7}" +
              "".join(f"{counts[fmt].get(c, 0):>11}" for c in classes))
    bad = sum(counts[f].get(c, 0) for f in counts for c in BAD)
    if bad or not all(sum(counts[f].values()) for f in formats):
        print(f"campaign: FAILED: {bad} bad runs (saved in {args.save})" if bad else
              "campaign: FAILED: a format ran no mutant within the budget", file=sys.stderr)
        return 1
    print("campaign: passed: no crash, hang, leftover file, multi-line error or changed output")
    return 0


if __name__ == "__main__":
    sys.exit(main())
