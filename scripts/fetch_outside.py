#!/usr/bin/env python3
"""Fetch the outside benchmark: 3D meshes that nobody in this project made.

    python3 scripts/fetch_outside.py [--out DIR] [--only NAME ...] [--manifest FILE]
    python3 scripts/fetch_outside.py --list

Reads scripts/outside/manifest.toml. For each `[[mesh]]` it downloads the package at its pinned
version with the registry's ordinary client (npm: `npm pack`, PyPI: `pip download --no-deps`,
Debian: `apt-get download` + `dpkg-deb --fsys-tarfile`), pulls the one file out of the archive
(`path`; `!` separates the levels of an archive inside the archive, a trailing `.gz` is
decompressed), checks its sha256, and converts it to what `neus-aug synth --mesh` reads:
a binary little-endian PLY of triangles (`float x y z`, `list uchar uint vertex_indices`),
duplicate vertices merged, unused vertices dropped, faces turned outward (positive volume).
The converted mesh is measured (faces, connected parts, Euler characteristic) and must match the
manifest, so a changed converter cannot slip in a different surface.

Writes DIR/<name>.ply (default target/outside/) through a temporary file and a rename, plus a
stamp DIR/<name>.sha256 ("<source sha256> <ply sha256>"); a mesh whose PLY and stamp agree with
the manifest is skipped. Each package is downloaded once per run, into a temporary folder that is
removed afterwards. Prints one line per mesh and exits 1 naming every mesh that failed. A manifest
entry with an empty `sha256` (or missing measurements) fails with the values to write in.
"""

import _pyenv

_pyenv.ensure({"numpy": "numpy", "trimesh": "trimesh", "scipy": "scipy"})

import argparse  # noqa: E402
import gzip  # noqa: E402
import hashlib  # noqa: E402
import io  # noqa: E402
import os  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tarfile  # noqa: E402
import tempfile  # noqa: E402
import zipfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sparse  # noqa: E402
import scipy.sparse.csgraph as csgraph  # noqa: E402
import trimesh  # noqa: E402

try:
    import tomllib  # noqa: E402  (Python >= 3.11)
except ModuleNotFoundError:  # pragma: no cover
    _pyenv.ensure({"tomli": "tomli"})
    import tomli as tomllib  # noqa: E402

HERE = Path(__file__).resolve().parent
MANIFEST = HERE / "outside" / "manifest.toml"
DEFAULT_OUT = _pyenv.ROOT / "target" / "outside"
REQUIRED = ("name", "registry", "package", "version", "path", "format", "license", "traits")
MEASURED = ("faces", "components", "euler", "genus")


class FetchError(Exception):
    """A mesh could not be fetched, checked or converted; the message says why."""


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def run(cmd: list[str], cwd: Path) -> None:
    """Run a registry client; a failure raises FetchError with the tail of its output."""
    try:
        done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    except FileNotFoundError:
        raise FetchError(f"`{cmd[0]}` is not installed (needed for: {' '.join(cmd)})") from None
    if done.returncode != 0:
        tail = [line[:160] for line in (done.stderr or done.stdout).strip().splitlines()[-3:]]
        raise FetchError(f"`{' '.join(cmd)}` failed (exit {done.returncode}): {' | '.join(tail)}")


def wheel_args(archive: str) -> list[str]:
    """pip options that select exactly the wheel `archive` (name-ver-py-abi-platform.whl)."""
    _, _, py, abi, plat = archive[: -len(".whl")].split("-")
    impl, ver = py[:2], py[2:]
    return ["--only-binary", ":all:", "--implementation", impl, "--python-version",
            f"{ver[0]}.{ver[1:]}", "--abi", abi, "--platform", plat]


def download(entry: dict, dest: Path) -> Path:
    """Download the entry's package archive into `dest`; returns the archive's path."""
    reg, pkg, ver = entry["registry"], entry["package"], entry["version"]
    if reg == "npm":
        run(["npm", "pack", "--loglevel=error", f"{pkg}@{ver}"], dest)
    elif reg == "pypi":
        archive = entry.get("archive", "")
        how = wheel_args(archive) if archive.endswith(".whl") else ["--no-binary", ":all:"]
        pip = [sys.executable, "-m", "pip", "download", "-q", "--disable-pip-version-check"]
        run([*pip, "--no-deps", *how, "-d", str(dest), f"{pkg}=={ver}"], dest)
    elif reg == "debian":
        try:
            run(["apt-get", "download", "-q", f"{pkg}={ver}"], dest)
        except FetchError:
            if os.geteuid() != 0:
                raise
            run(["apt-get", "update", "-qq"], dest)  # empty or stale package lists
            run(["apt-get", "download", "-q", f"{pkg}={ver}"], dest)
    else:
        raise FetchError(f"unknown registry '{reg}' (npm, pypi or debian)")
    found = sorted(p for p in dest.iterdir() if p.is_file())
    want = entry.get("archive")
    if want:
        found = [p for p in found if p.name == want]
    if len(found) != 1:
        raise FetchError(f"expected one archive{' ' + want if want else ''} from {reg} {pkg} {ver}, "
                         f"got {[p.name for p in found]}")
    return found[0]


def read_member(container: Path, member: str, scratch: Path) -> bytes:
    """The bytes of `member` inside a .deb, tar(.gz), .tgz, .whl or .zip file."""
    name = container.name
    if name.endswith(".deb"):
        tar_path = scratch / (name + ".tar")
        if not tar_path.exists():
            with open(tar_path, "wb") as fh:
                done = subprocess.run(["dpkg-deb", "--fsys-tarfile", str(container)], stdout=fh)
            if done.returncode != 0:
                tar_path.unlink()
                raise FetchError(f"`dpkg-deb --fsys-tarfile {name}` failed")
        container, name = tar_path, tar_path.name
    if name.endswith((".whl", ".zip")):
        with zipfile.ZipFile(container) as zf:
            try:
                return zf.read(member)
            except KeyError:
                raise FetchError(f"{member} is not in {container.name}") from None
    if name.endswith((".tar", ".tar.gz", ".tgz")):
        with tarfile.open(container) as tf:
            for info in tf:
                if info.isfile() and info.name.removeprefix("./") == member.removeprefix("./"):
                    return tf.extractfile(info).read()
        raise FetchError(f"{member} is not in {container.name}")
    raise FetchError(f"do not know how to open {container.name}")


def extract(archive: Path, path: str, scratch: Path, cache: dict) -> bytes:
    """Follow `a!b!c` through nested archives (each level cached as a file); gunzip a `.gz`."""
    levels = path.split("!")
    container = archive
    for member in levels[:-1]:
        key = (str(container), member)
        if key not in cache:
            nested = scratch / f"nested{len(cache)}-{Path(member).name}"
            nested.write_bytes(read_member(container, member, scratch))
            cache[key] = nested
        container = cache[key]
    data = read_member(container, levels[-1], scratch)
    return gzip.decompress(data) if levels[-1].endswith(".gz") else data


def to_triangles(data: bytes, fmt: str) -> tuple[np.ndarray, np.ndarray]:
    """Parse a mesh file; merged vertices (float32), triangles (uint32), outward orientation."""
    try:
        mesh = trimesh.load(io.BytesIO(data), file_type=fmt, process=False, force="mesh")
    except Exception as e:  # trimesh raises many kinds for a malformed file
        raise FetchError(f"trimesh cannot read it as {fmt}: {e}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise FetchError(f"no triangles in the {fmt} file")
    mesh.merge_vertices(merge_tex=True, merge_norm=True)  # by position only
    mesh.remove_unreferenced_vertices()
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if mesh.volume < 0:  # signed volume: negative when the faces point inward
        faces = faces[:, ::-1]
    return np.asarray(mesh.vertices, dtype=np.float32), faces.astype(np.uint32)


def measure(vertices: np.ndarray, faces: np.ndarray) -> dict:
    """Faces, vertex-connected parts, Euler characteristic V - E + F, genus (sum over parts,
    -1 when not defined: a boundary or an edge shared by more than two faces), edge defects."""
    nv = len(vertices)
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1).astype(np.int64)
    keys, counts = np.unique(edges[:, 0] * nv + edges[:, 1], return_counts=True)
    a, b = keys // nv, keys % nv
    graph = sparse.coo_matrix((np.ones(len(keys)), (a, b)), shape=(nv, nv))
    parts = csgraph.connected_components(graph, directed=False)[0]
    euler = nv - len(keys) + len(faces)
    boundary, nonmanifold = int((counts == 1).sum()), int((counts > 2).sum())
    closed = boundary == 0 and nonmanifold == 0 and euler % 2 == 0
    genus = parts - euler // 2 if closed else -1
    return {"faces": len(faces), "components": int(parts), "euler": int(euler), "genus": int(genus),
            "boundary_edges": boundary, "nonmanifold_edges": nonmanifold}


def ply_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """Binary little-endian PLY, the layout dtu_eval::ply writes and reads."""
    header = (f"ply\nformat binary_little_endian 1.0\ncomment outside benchmark, see "
              f"scripts/outside/manifest.toml\nelement vertex {len(vertices)}\nproperty float x\n"
              f"property float y\nproperty float z\nelement face {len(faces)}\n"
              "property list uchar uint vertex_indices\nend_header\n")
    rows = np.empty(len(faces), dtype=[("n", "u1"), ("i", "<u4", (3,))])
    rows["n"], rows["i"] = 3, faces
    return header.encode() + vertices.astype("<f4").tobytes() + rows.tobytes()


def write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def up_to_date(entry: dict, out: Path) -> bool:
    ply, stamp = out / f"{entry['name']}.ply", out / f"{entry['name']}.sha256"
    if not (ply.exists() and stamp.exists()):
        return False
    src, _, ply_sha = stamp.read_text().strip().partition(" ")
    return src == entry["sha256"] and ply_sha == sha256(ply.read_bytes())


def convert(entry: dict, data: bytes, out: Path) -> str:
    """Check the source bytes and measurements against the manifest, write the PLY and stamp."""
    got = sha256(data)
    if got != entry.get("sha256"):
        if entry.get("sha256"):  # a different file: do not even parse it
            raise FetchError(f"sha256 is {got}, manifest says {entry['sha256']}")
    vertices, faces = to_triangles(data, entry["format"])
    m = measure(vertices, faces)
    wrong = [f"{k} = {m[k]}" for k in MEASURED if entry.get(k) != m[k]]
    if got != entry.get("sha256"):
        wrong.insert(0, f'sha256 = "{got}"')
    if wrong:  # a new entry (empty sha256) lands here too, with all the values to write in
        raise FetchError(f"manifest disagrees; measured {', '.join(wrong)}; {m}")
    ply = ply_bytes(vertices, faces)
    write_atomic(out / f"{entry['name']}.ply", ply)
    write_atomic(out / f"{entry['name']}.sha256", f"{got} {sha256(ply)}\n".encode())
    return (f"faces={m['faces']} parts={m['components']} genus={m['genus']} "
            f"boundary={m['boundary_edges']} nonmanifold={m['nonmanifold_edges']}")


def load_manifest(path: Path) -> list[dict]:
    try:
        meshes = tomllib.loads(path.read_text())["mesh"]
    except (OSError, KeyError, tomllib.TOMLDecodeError) as e:
        sys.exit(f"cannot read the manifest {path}: {e!r}")
    for i, entry in enumerate(meshes):
        missing = [k for k in REQUIRED if k not in entry]
        if missing:
            sys.exit(f"{path}: [[mesh]] #{i + 1} ({entry.get('name', '?')}) lacks {missing}")
    names = [e["name"] for e in meshes]
    if len(set(names)) != len(names):
        sys.exit(f"{path}: duplicate mesh names")
    return meshes


def print_table(meshes: list[dict]) -> None:
    print(f"{'name':16} {'source':42} {'genus':>5} {'parts':>5} {'faces':>7}  traits")
    for e in meshes:
        source = f"{e['registry']}:{e['package']}@{e['version']}"
        print(f"{e['name']:16} {source:42} {e.get('genus', '?'):>5} {e.get('components', '?'):>5} "
              f"{e.get('faces', '?'):>7}  {', '.join(e['traits'])}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--manifest", type=Path, default=MANIFEST)
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="default: target/outside")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="fetch only these meshes")
    ap.add_argument("--list", action="store_true", help="print the manifest's table and exit")
    args = ap.parse_args()
    meshes = load_manifest(args.manifest)
    if args.list:
        print_table(meshes)
        return
    if args.only:
        unknown = set(args.only) - {e["name"] for e in meshes}
        if unknown:
            sys.exit(f"not in the manifest: {sorted(unknown)}")
        meshes = [e for e in meshes if e["name"] in args.only]
    args.out.mkdir(parents=True, exist_ok=True)
    failed = []
    todo: dict[tuple, list[dict]] = {}
    for e in meshes:
        if up_to_date(e, args.out):
            print(f"skip {e['name']:16} {args.out / (e['name'] + '.ply')} (present, hash matches)")
        else:
            todo.setdefault((e["registry"], e["package"], e["version"], e.get("archive")), []).append(e)
    for (reg, pkg, ver, _), group in todo.items():
        with tempfile.TemporaryDirectory(prefix="outside-") as tmp:
            scratch, cache = Path(tmp), {}
            (scratch / "dl").mkdir()
            try:
                archive = download(group[0], scratch / "dl")
            except FetchError as err:
                for e in group:
                    print(f"FAIL {e['name']:16} {reg}:{pkg}@{ver}: {err}")
                    failed.append(e["name"])
                continue
            for e in group:
                try:
                    info = convert(e, extract(archive, e["path"], scratch, cache), args.out)
                    print(f"ok   {e['name']:16} {args.out / (e['name'] + '.ply')} {info}")
                except FetchError as err:
                    print(f"FAIL {e['name']:16} {reg}:{pkg}@{ver} {e['path']}: {err}")
                    failed.append(e["name"])
    if failed:
        sys.exit(f"{len(failed)} of {len(meshes)} meshes failed: {', '.join(failed)}")
    print(f"{len(meshes)} meshes in {args.out}")


if __name__ == "__main__":
    main()
