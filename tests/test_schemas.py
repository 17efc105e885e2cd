#!/usr/bin/python3
"""JSON output against schemas/: runs the mimic binary (synth -> ingest ->
info/list) and validates every JSON document it writes or prints with
Debian's python3-jsonschema. Prints 'N passed, N failed'."""
import json
import os
import subprocess
import sys
import tempfile

import jsonschema

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MIMIC = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("MIMIC_BIN", "mimic")


def load(name):
    with open(os.path.join(ROOT, "schemas", name)) as f:
        return json.load(f)


SCHEMAS = {s["$id"]: s for s in map(load, ["info.schema.json", "list.schema.json", "landmarks.schema.json",
                                            "index.schema.json", "query.schema.json", "transfer.schema.json",
                                            "morph.schema.json", "landmark-frames.schema.json",
                                            "vest-udp.schema.json", "vest-replay.schema.json",
                                            "serve-status.schema.json", "serve-avatar.schema.json",
                                            "serve-transfer-request.schema.json", "serve-error.schema.json",
                                            "store-check.schema.json", "pair-annotations.schema.json", "pair-cameras.schema.json",
                                            "pairs-coverage.schema.json", "complete.schema.json", "register.schema.json",
                                            "pairs-templates.schema.json", "pairs-sample.schema.json",
                                            "pairs-retrieve.schema.json", "pairs-complete.schema.json",
                                            "store-copy.schema.json", "serve-session.schema.json",
                                            "serve-session-request.schema.json", "serve-sessions.schema.json",
                                            "landmarks-show.schema.json"])}


def validator(schema_id):
    schema = SCHEMAS[schema_id]
    resolver = jsonschema.RefResolver(base_uri=schema_id, referrer=schema, store=SCHEMAS)
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    return cls(schema, resolver=resolver)


def run(*args):
    p = subprocess.run([MIMIC, *args], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"mimic {' '.join(args)} exited {p.returncode}: {p.stderr.strip()}")
    return p.stdout


def ply_landmarks(path, landmarks):
    """The landmark positions of a binary little-endian PLY that mimic synth wrote."""
    import struct
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    nv = next(int(l.split()[2]) for l in data[:end].decode().splitlines() if l.startswith("element vertex"))
    v = struct.unpack_from("<%df" % (3 * nv), data, end)
    return [list(v[3 * m["vertex"]:3 * m["vertex"] + 3]) for m in landmarks["landmarks"]]


# A tiny BVH (Y up, left +X, T-pose rest) for the simulated vest.
VEST_BVH = """HIERARCHY
ROOT Hips
{
 OFFSET 0 95 0
 CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
 JOINT Chest
 {
  OFFSET 0 25 0
  CHANNELS 3 Zrotation Xrotation Yrotation
  JOINT Head
  {
   OFFSET 0 30 0
   CHANNELS 3 Zrotation Xrotation Yrotation
   End Site
   {
    OFFSET 0 20 0
   }
  }
  JOINT LeftArm
  {
   OFFSET 17 25 0
   CHANNELS 3 Zrotation Xrotation Yrotation
   End Site
   {
    OFFSET 28 0 0
   }
  }
  JOINT RightArm
  {
   OFFSET -17 25 0
   CHANNELS 3 Zrotation Xrotation Yrotation
   End Site
   {
    OFFSET -28 0 0
   }
  }
 }
 JOINT LeftUpLeg
 {
  OFFSET 9 0 0
  CHANNELS 3 Zrotation Xrotation Yrotation
  End Site
  {
   OFFSET 0 -45 0
  }
 }
 JOINT RightUpLeg
 {
  OFFSET -9 0 0
  CHANNELS 3 Zrotation Xrotation Yrotation
  End Site
  {
   OFFSET 0 -45 0
  }
 }
}
MOTION
Frames: 3
Frame Time: 0.1
0 95 0 0 0 0 0 0 0 0 0 0 -80 0 0 80 0 0 0 0 0 0 0 0
0 95 0 0 0 10 0 5 0 0 0 0 -70 10 0 70 -10 0 0 20 0 0 -20 0
0 95 0 0 0 20 0 10 0 0 0 0 -60 20 0 60 -20 0 0 30 0 0 -30 0
"""


def vest_cases(d):
    """mimic vest simulate -> recording -> replay (sensor frames and landmarks), and --expected."""
    bvh, rec, exp = (os.path.join(d, n) for n in ("vest.bvh", "vest.rec", "vest-expected.jsonl"))
    with open(bvh, "w") as f:
        f.write(VEST_BVH)
    run("vest", "simulate", "--motion", bvh, "--rate", "20", "--out", rec, "--expected", exp)
    sensors = [json.loads(x) for x in run("vest", "replay", rec).splitlines()]
    marks = [json.loads(x) for x in run("vest", "replay", rec, "--avatar", "synth", "--pose", "t").splitlines()]
    with open(exp) as f:
        expected = [json.loads(x) for x in f]
    if not sensors or not marks or not expected:
        raise RuntimeError("mimic vest replay printed nothing")
    # the lines carry the 17 segment orientations (issue 17), or the cases below prove nothing about them
    for doc in (marks[0], marks[-1], expected[1]):
        if len(doc.get("orientations", {})) != 17:
            raise RuntimeError("a vest landmark line without its 17 orientations: %s" % list(doc))
    return [("/mimic/schemas/vest-replay.schema.json", sensors[0], "vest replay (sensor frame)"),
            ("/mimic/schemas/vest-replay.schema.json", marks[-1], "vest replay --avatar (landmarks, orientations)"),
            ("/mimic/schemas/vest-udp.schema.json", expected[1], "vest simulate --expected (landmarks, orientations)"),
            ("/mimic/schemas/landmark-frames.schema.json", marks[0], "vest replay landmarks as a query frame"),
            ("/mimic/schemas/landmark-frames.schema.json", marks[-1], "vest replay line as a transfer frame"),
            ("/mimic/schemas/landmark-frames.schema.json", {"frames": [expected[1]]},
             "vest simulate --expected line in a batch")]


def store_check_cases(d, store, data):
    """mimic store check --json on an intact store (exit 0) and on a copy
    with one byte flipped in a template's positions (exit 1)."""
    import shutil
    clean = json.loads(run("store", "check", "--store", store, "--json"))
    damaged = os.path.join(d, "damaged")
    os.makedirs(damaged)
    shutil.copy(os.path.join(store, "data.mdb"), os.path.join(damaged, "data.mdb"))
    with open(os.path.join(data, "synth_s00_p01.ply"), "rb") as f:
        ply = f.read()
    positions = ply[ply.index(b"end_header\n") + len(b"end_header\n"):][:240]
    with open(os.path.join(damaged, "data.mdb"), "r+b") as f:
        db = bytearray(f.read())
        at = db.index(positions) + 100
        db[at] ^= 0x10
        f.seek(0)
        f.write(db)
    p = subprocess.run([MIMIC, "store", "check", "--store", damaged, "--json"], capture_output=True, text=True)
    if p.returncode != 1:
        raise RuntimeError(f"mimic store check on a damaged store exited {p.returncode}: {p.stderr.strip()}")
    found = json.loads(p.stdout)
    copied = json.loads(run("store", "copy", store, os.path.join(d, "copied"), "--json"))
    return [("/mimic/schemas/store-check.schema.json", clean, "store check (clean)"),
            ("/mimic/schemas/store-check.schema.json", found, "store check (a flipped byte)"),
            ("/mimic/schemas/store-copy.schema.json", copied, "store copy")]


def read_ply(path):
    """Positions and faces of a binary little-endian triangle PLY as mimic synth writes it."""
    import struct
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    head = data[:end].decode().splitlines()
    nv = next(int(l.split()[2]) for l in head if l.startswith("element vertex"))
    nf = next(int(l.split()[2]) for l in head if l.startswith("element face"))
    v = struct.unpack_from("<%df" % (3 * nv), data, end)
    pos = [list(v[3 * i:3 * i + 3]) for i in range(nv)]
    faces, at = [], end + 12 * nv
    for _ in range(nf):
        if data[at] != 3:
            raise RuntimeError(f"{path}: a face that is not a triangle")
        faces.append(list(struct.unpack_from("<3i", data, at + 1)))
        at += 13
    return pos, faces


def write_ply(path, pos, faces):
    import struct
    with open(path, "wb") as f:
        f.write(("ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty float x\nproperty float y\n"
                 "property float z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n"
                 % (len(pos), len(faces))).encode())
        for p in pos:
            f.write(struct.pack("<3f", *p))
        for t in faces:
            f.write(struct.pack("<B3i", 3, *t))


def subdivide(pos, faces):
    """1->4 midpoint subdivision: the original vertices keep their index, one new vertex per edge."""
    pos, mid, out = [list(p) for p in pos], {}, []

    def m(a, b):
        key = (min(a, b), max(a, b))
        if key not in mid:
            mid[key] = len(pos)
            pos.append([(pos[a][k] + pos[b][k]) / 2 for k in range(3)])
        return mid[key]
    for a, b, c in faces:
        ab, bc, ca = m(a, b), m(b, c), m(c, a)
        out += [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
    return pos, out


def register_cases(d, store, data, landmarks):
    """mimic register --json onto two meshes of other connectivities: a
    body of a subject the store does not hold, made by mimic synth at
    another vertex count (its landmark map as the sidecar), and a store
    body subdivided 1->4 here (its landmark positions given with
    --landmarks). Both must really be another connectivity. Then ingest
    --register into a copy of the store (list --json with the figures) and
    store check on a copy whose registration record is damaged."""
    import shutil
    store_pos, store_faces = read_ply(os.path.join(data, "synth_s00_p00.ply"))
    other = os.path.join(d, "other")
    run("synth", "--out", other, "--subjects", "3", "--poses", "2", "--vertices", "900")
    foreign = os.path.join(d, "foreign.ply")
    shutil.copy(os.path.join(other, "synth_s02_p01.ply"), foreign)
    shutil.copy(os.path.join(other, "landmarks.json"), os.path.join(d, "foreign.landmarks.json"))
    fpos, ffaces = read_ply(foreign)
    pos, faces = subdivide(*read_ply(os.path.join(data, "synth_s01_p01.ply")))
    sub = os.path.join(d, "subdivided.ply")
    write_ply(sub, pos, faces)
    sub_lm = os.path.join(d, "subdivided-landmarks.json")
    with open(sub_lm, "w") as f:
        json.dump({"landmarks": [pos[m["vertex"]] for m in landmarks["landmarks"]]}, f)
    for n, fc, what in ((len(fpos), ffaces, "synth --vertices 900"), (len(pos), faces, "subdivided")):
        if n == len(store_pos) or fc == store_faces:
            raise RuntimeError(f"{what}: the same connectivity as the store's ({n} vertices)")
    a = json.loads(run("register", "--store", store, foreign, "-o", os.path.join(d, "reg-a.ply"), "--json"))
    b = json.loads(run("register", "--store", store, "--landmarks", sub_lm, sub, "-o", os.path.join(d, "reg-b.obj"),
                       "--json"))
    for doc, n, src in ((a, len(fpos), "foreign.landmarks.json"), (b, len(pos), sub_lm)):
        if doc["vertices"] != n or doc["store_vertices"] != len(store_pos) or not doc["landmarks_from"].endswith(src):
            raise RuntimeError(f"mimic register --json: vertices {doc['vertices']} (want {n}), store_vertices "
                               f"{doc['store_vertices']} (want {len(store_pos)}), landmarks_from {doc['landmarks_from']}")
    # ingest --register into a copy of the store: list shows the figures;
    # then the registration record damaged: store check names its table
    reg_store, damaged = os.path.join(d, "reg-store"), os.path.join(d, "reg-damaged")
    for x in (reg_store, damaged):
        os.makedirs(x)
    shutil.copy(os.path.join(store, "data.mdb"), os.path.join(reg_store, "data.mdb"))
    run("ingest", "--store", reg_store, "--register", foreign)
    listed = json.loads(run("list", "--store", reg_store, "--json"))
    if [t["registration"]["source_vertices"] for t in listed if "registration" in t] != [len(fpos)]:
        raise RuntimeError("mimic list --json after ingest --register: no registration of the foreign mesh listed")
    shutil.copy(os.path.join(reg_store, "data.mdb"), os.path.join(damaged, "data.mdb"))
    with open(os.path.join(damaged, "data.mdb"), "r+b") as f:
        db = bytearray(f.read())
        at = db.index(b"MRG4") + 40  # the registration's mean_mm (db/registration.c; MRG4: with its quality)
        db[at] ^= 0x10
        f.seek(0)
        f.write(db)
    p = subprocess.run([MIMIC, "store", "check", "--store", damaged, "--json"], capture_output=True, text=True)
    found = json.loads(p.stdout) if p.returncode == 1 else None
    if not found or not any(x["table"] == "registrations" for x in found["problems"]):
        raise RuntimeError(f"mimic store check on a damaged registration exited {p.returncode}, "
                           f"found no problem in 'registrations': {p.stdout.strip()} {p.stderr.strip()}")
    return [("/mimic/schemas/register.schema.json", a, "register (another synth connectivity, a map sidecar)"),
            ("/mimic/schemas/register.schema.json", b, "register (subdivided 1->4, positions with --landmarks)"),
            ("/mimic/schemas/list.schema.json", listed, "list (a template registered by ingest --register)"),
            ("/mimic/schemas/store-check.schema.json", found, "store check (a damaged registration)")]


def serve_cases(store, one, vest_rec):
    """mimic serve's JSON answers (and a transfer request), fetched over HTTP;
    then its status with a vest recording played to the end."""
    import time
    import urllib.error
    import urllib.request
    p = subprocess.Popen([MIMIC, "serve", "--store", store, "--avatar", "1", "--listen", "127.0.0.1:0"],
                         stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    v = subprocess.Popen([MIMIC, "serve", "--store", store, "--avatar", "1", "--listen", "127.0.0.1:0",
                          "--vest", vest_rec, "--vest-pose", "t"],
                         stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        url = p.stdout.readline().strip().rstrip("/")

        def fetch(path, body=None):
            data = None if body is None else body.encode()
            headers = {} if body is None else {"Content-Type": "application/json"}
            try:
                with urllib.request.urlopen(urllib.request.Request(url + path, data=data, headers=headers),
                                            timeout=60) as r:
                    return json.loads(r.read())
            except urllib.error.HTTPError as e:
                return json.loads(e.read())
        cases = [("/mimic/schemas/serve-status.schema.json", fetch("/api/status"), "serve /api/status"),
                 ("/mimic/schemas/serve-avatar.schema.json", fetch("/api/avatar"), "serve /api/avatar"),
                 ("/mimic/schemas/query.schema.json", fetch("/api/query?k=3", json.dumps(one)), "serve /api/query"),
                 ("/mimic/schemas/serve-error.schema.json", fetch("/api/query", "{\"landmarks\": ["),
                  "serve error (malformed JSON)"),
                 ("/mimic/schemas/serve-error.schema.json", fetch("/nothing"), "serve error (unknown route)"),
                 ("/mimic/schemas/serve-transfer-request.schema.json", dict(one, template=4),
                  "serve transfer request")]
        add = {"name": "second", "avatar": "2", "key_rate": 30}
        cases += [("/mimic/schemas/serve-session-request.schema.json", add, "serve session request"),
                  ("/mimic/schemas/serve-sessions.schema.json", {"sessions": [add, {"name": "v", "avatar": "3",
                                                                                   "vest": vest_rec}]},
                   "serve --sessions file"),
                  ("/mimic/schemas/serve-session.schema.json", fetch("/api/sessions", json.dumps(add)),
                   "serve POST /api/sessions"),
                  ("/mimic/schemas/serve-session.schema.json", fetch("/api/sessions/second"),
                   "serve /api/sessions/NAME"),
                  ("/mimic/schemas/serve-status.schema.json", fetch("/api/status"), "serve /api/status (2 sessions)"),
                  ("/mimic/schemas/serve-error.schema.json", fetch("/api/sessions", json.dumps(add)),
                   "serve error (a session name taken)")]
        cases += [("/mimic/schemas/serve-session.schema.json", item, "serve /api/sessions item")
                  for item in fetch("/api/sessions")["sessions"]]
        url = v.stdout.readline().strip().rstrip("/")
        for _ in range(600):
            status = fetch("/api/status")
            if status["vest"]["state"] != "streaming":
                break
            time.sleep(0.1)
        cases.append(("/mimic/schemas/serve-status.schema.json", status, "serve /api/status (vest ended)"))
    finally:
        for proc in (p, v):
            proc.terminate()
            proc.wait(timeout=60)
    return cases


# Two people of one take, CMU joint names, every rotation zero (pairs cases).
PAIR_SKELETON = [("Hips", -1, (0, 0, 0)), ("LeftUpLeg", 0, (1.5, -1, 0)), ("LeftLeg", 1, (0, -7.5, 0)),
                 ("LeftFoot", 2, (0, -7.5, 0)), ("RightUpLeg", 0, (-1.5, -1, 0)), ("RightLeg", 4, (0, -7.5, 0)),
                 ("RightFoot", 5, (0, -7.5, 0)), ("Spine", 0, (0, 2, 0)), ("Spine1", 7, (0, 3, 0)),
                 ("Neck", 8, (0, 3, 0)), ("Head", 9, (0, 1.5, 0)), ("LeftArm", 8, (3, 2.5, 0)),
                 ("LeftForeArm", 11, (5, 0, 0)), ("LeftHand", 12, (4.5, 0, 0)), ("RightArm", 8, (-3, 2.5, 0)),
                 ("RightForeArm", 14, (-5, 0, 0)), ("RightHand", 15, (-4.5, 0, 0))]


def pair_bvh(person, frames=12):
    lines = ["HIERARCHY"]

    def block(j):
        name, _, off = PAIR_SKELETON[j]
        lines.append(("JOINT " if j else "ROOT ") + name)
        lines.append("{")
        lines.append("OFFSET %g %g %g" % off)
        lines.append("CHANNELS 3 Zrotation Yrotation Xrotation" if j else
                     "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation")
        kids = [k for k, (_, p, _) in enumerate(PAIR_SKELETON) if p == j]
        for k in kids:
            block(k)
        if not kids:
            lines.extend(["End Site", "{", "OFFSET 0 0 1", "}"])
        lines.append("}")
    block(0)
    lines += ["MOTION", "Frames: %d" % frames, "Frame Time: 0.0083333"]
    for f in range(frames):
        x = 12 - 0.2 * f if person else 0.3 * f
        lines.append(" ".join(["%g" % x, "16", "3" if person else "0"] + ["0"] * (3 + 3 * (len(PAIR_SKELETON) - 1))))
    return "\n".join(lines) + "\n"


def pairs_cases(d):
    a, b = os.path.join(d, "pa.bvh"), os.path.join(d, "pb.bvh")
    for path, person in ((a, 0), (b, 1)):
        with open(path, "w") as f:
            f.write(pair_bvh(person))
    ann, cams, frames = os.path.join(d, "ann.json"), os.path.join(d, "cams.json"), os.path.join(d, "frames.jsonl")
    run("pairs", "annotate", "--pair", a + "," + b, "--every", "3", "--views", "2", "-o", ann, "--cameras", cams)
    run("pairs", "export", "--pair", a + "," + b, "--every", "2", "-o", frames)
    cov = json.loads(run("pairs", "coverage", "--truth", a + "," + b, "--every", "3", "--offset", "1",
                         "--samples", frames, "--json"))
    video = os.path.join(d, "video.json")
    run("pairs", "annotate", "--pair", a + "," + b, "--every", "1", "--views", "2", "--video", "-o", video)
    sampled = json.loads(run("pairs", "sample", "--prior", a + "," + b, "--annotations", video, "--samples", "20",
                             "--chains", "2", "--json", "-o", os.path.join(d, "sampled.jsonl")))
    retrieved = json.loads(run("pairs", "retrieve", "--annotations", ann, "--samples", frames, "--truth", a + "," + b,
                               "--cameras", cams, "--json", "-o", os.path.join(d, "lifted.jsonl")))
    plain = json.loads(run("pairs", "retrieve", "--annotations", ann, "--samples", frames, "--json",
                           "-o", os.path.join(d, "lifted.jsonl")))
    completed = json.loads(run("pairs", "complete", "--pairs", frames, "--missing", "B.l_elbow,B.l_wrist", "--samples",
                               frames, "--json", "-o", os.path.join(d, "completed.jsonl")))
    with open(ann) as f1, open(cams) as f2, open(video) as f3:
        cases = [("/mimic/schemas/pair-annotations.schema.json", json.load(f3), "pairs annotate --video"),
                 ("/mimic/schemas/pairs-sample.schema.json", sampled, "pairs sample --json"),
                 ("/mimic/schemas/pairs-retrieve.schema.json", retrieved, "pairs retrieve --truth --cameras --json"),
                 ("/mimic/schemas/pairs-retrieve.schema.json", plain, "pairs retrieve --json"),
                 ("/mimic/schemas/pairs-complete.schema.json", completed, "pairs complete --json")]
        return [("/mimic/schemas/pair-annotations.schema.json", json.load(f1), "pairs annotate"),
                ("/mimic/schemas/pair-cameras.schema.json", json.load(f2), "pairs annotate --cameras"),
                ("/mimic/schemas/pairs-coverage.schema.json", cov, "pairs coverage --json")] + cases


def pairs_templates_cases(d, store, samples):
    """mimic pairs templates --json: the pose-pairs pairs_cases exported
    become templates of a copy of the (indexed) store; list shows them."""
    import shutil
    copy = os.path.join(d, "sampled-store")
    os.makedirs(copy)
    shutil.copy(os.path.join(store, "data.mdb"), os.path.join(copy, "data.mdb"))
    doc = json.loads(run("pairs", "templates", "--store", copy, "--samples", samples, "--avatar", "1", "--max", "2",
                         "--json"))
    listed = json.loads(run("list", "--store", copy, "--json"))
    sampled = [t["id"] for t in listed if t["source"].startswith("sampled:")]
    if not doc["ids"] or sorted(doc["ids"]) != sampled:
        raise RuntimeError(f"mimic pairs templates --json: ids {doc['ids']}, list shows sampled templates {sampled}")
    return [("/mimic/schemas/pairs-templates.schema.json", doc, "pairs templates --json"),
            ("/mimic/schemas/list.schema.json", listed, "list (sampled templates)")]


def main():
    passed = failed = 0
    with tempfile.TemporaryDirectory(prefix="mimic-schemas-") as d:
        data, store, empty = os.path.join(d, "bodies"), os.path.join(d, "store"), os.path.join(d, "empty")
        run("synth", "--out", data, "--subjects", "2", "--poses", "2", "--vertices", "1500")
        run("ingest", "--store", store, data)
        # an empty store: connectivity and landmarks are null
        os.makedirs(empty)
        subprocess.run([MIMIC, "ingest", "--store", empty, os.path.join(d, "nothing")], capture_output=True)
        with open(os.path.join(data, "landmarks.json")) as f:
            landmarks = json.load(f)
        # recognition: index, then query one frame and a batch with a lost landmark
        info_before = json.loads(run("info", "--store", store, "--json"))
        index_doc = json.loads(run("index", "--store", store, "--json", "--features", "20"))
        frames = {"frames": [{"landmarks": ply_landmarks(os.path.join(data, f), landmarks)}
                             for f in ("synth_s00_p00.ply", "synth_s01_p01.ply")]}
        frames["frames"][1]["landmarks"][5] = None
        frames_path = os.path.join(d, "frames.json")
        with open(frames_path, "w") as f:
            json.dump(frames, f)
        query_doc = json.loads(run("query", "--store", store, "--landmarks", frames_path, "-k", "2", "--json"))
        # transfer: mode (a), and landmarks alone (the template from the index)
        one = {"landmarks": frames["frames"][0]["landmarks"]}
        one_path = os.path.join(d, "one.json")
        with open(one_path, "w") as f:
            json.dump(one, f)
        transfer_a = json.loads(run("transfer", "--store", store, "--avatar", "1", "--template", "4",
                                    "-o", os.path.join(d, "a.obj"), "--json"))
        transfer_l = json.loads(run("transfer", "--store", store, "--avatar", "1", "--landmarks", one_path,
                                    "-o", os.path.join(d, "l.off"), "--json", "--iterations", "1"))
        morph_doc = json.loads(run("morph", "--store", store, "--avatar", "1", "--keys", "2,3,4",
                                   "--frames-between", "2", "-o", os.path.join(d, "m.glb"), "--json"))
        cases = [
            ("/mimic/schemas/transfer.schema.json", transfer_a, "transfer (template only)"),
            ("/mimic/schemas/transfer.schema.json", transfer_l, "transfer (landmarks only, one iteration)"),
            ("/mimic/schemas/morph.schema.json", morph_doc, "morph"),
            ("/mimic/schemas/landmark-frames.schema.json", frames, "landmark frames (batch with a null)"),
            ("/mimic/schemas/landmark-frames.schema.json", one, "landmark frames (one frame)"),
            ("/mimic/schemas/info.schema.json", info_before, "info (no index)"),
            ("/mimic/schemas/info.schema.json", json.loads(run("info", "--store", store, "--json")), "info"),
            ("/mimic/schemas/index.schema.json", index_doc, "index"),
            ("/mimic/schemas/query.schema.json", query_doc, "query (batch, a missing landmark)"),
            ("/mimic/schemas/info.schema.json", json.loads(run("info", "--store", empty, "--json")), "info (empty store)"),
            ("/mimic/schemas/list.schema.json", json.loads(run("list", "--store", store, "--json")), "list"),
            ("/mimic/schemas/list.schema.json", json.loads(run("list", "--store", store, "--pose", "9", "--json")), "list (none)"),
            ("/mimic/schemas/landmarks.schema.json", landmarks, "synth landmarks.json"),
            ("/mimic/schemas/landmarks-show.schema.json",
             json.loads(run("landmarks", "show", os.path.join(data, "synth_s00_p00.ply"), "--landmarks",
                            os.path.join(data, "landmarks.json"), "--json")), "landmarks show (a file)"),
        ]
        check_cases = store_check_cases(d, store, data)
        cases += check_cases
        reg_cases = register_cases(d, store, data, landmarks)
        cases += reg_cases
        cases += pairs_cases(d)
        sampled_cases = pairs_templates_cases(d, store, os.path.join(d, "frames.jsonl"))
        cases += sampled_cases
        lost = {"frames": [{"landmarks": list(frames["frames"][0]["landmarks"])}, {"landmarks": list(one["landmarks"])}]}
        for k in (7, 8, 13):
            lost["frames"][0]["landmarks"][k] = None
        lost_path = os.path.join(d, "lost.json")
        with open(lost_path, "w") as f:
            json.dump(lost, f)
        cases.append(("/mimic/schemas/complete.schema.json",
                      json.loads(run("complete", "--store", store, "--landmarks", lost_path, "--json")),
                      "complete (3 lost, and a complete frame)"))
        for schema_id, doc, what in cases + vest_cases(d) + serve_cases(store, one, os.path.join(d, "vest.rec")):
            errors = list(validator(schema_id).iter_errors(doc))
            if errors:
                failed += 1
                print(f"FAIL {what}: {errors[0].message} at {list(errors[0].absolute_path)}")
            else:
                passed += 1
                print(f"ok   {what}")
        # the schemas must also reject what they should
        bad = json.loads(run("info", "--store", store, "--json"))
        bad["templates"] = "4"
        if list(validator("/mimic/schemas/info.schema.json").iter_errors(bad)):
            passed += 1
            print("ok   info schema rejects a string template count")
        else:
            failed += 1
            print("FAIL info schema accepted a string template count")
        bad = json.loads(json.dumps(check_cases[1][1]))
        if bad["problems"]:
            bad["problems"][0]["message"] = "checksum mismatch"
        if bad["problems"] and list(validator("/mimic/schemas/store-check.schema.json").iter_errors(bad)):
            passed += 1
            print("ok   store-check schema rejects a problem line without 'store damaged: '")
        else:
            failed += 1
            print("FAIL store-check schema accepted a problem line without 'store damaged: ' (or none was found)")
        bad = dict(query_doc)
        bad["frames"] = [dict(query_doc["frames"][0], probability=1.5)]
        if list(validator("/mimic/schemas/query.schema.json").iter_errors(bad)):
            passed += 1
            print("ok   query schema rejects a probability of 1.5")
        else:
            failed += 1
            print("FAIL query schema accepted a probability of 1.5")
        bad = {"frames": [{"landmarks": [[0, 0]] * 16}]}
        if list(validator("/mimic/schemas/landmark-frames.schema.json").iter_errors(bad)):
            passed += 1
            print("ok   landmark-frames schema rejects a 2-component point")
        else:
            failed += 1
            print("FAIL landmark-frames schema accepted a 2-component point")
        lm16 = frames["frames"][0]["landmarks"]
        v = validator("/mimic/schemas/landmark-frames.schema.json")
        bad_or = [{"landmarks": lm16, "orientations": {"l_elbow": [0, 0, 0, 1]}},
                  {"landmarks": lm16, "orientations": {"head": [0, 0, 1]}},
                  {"frames": [{"landmarks": lm16}], "orientations": {}}]
        good_or = {"landmarks": lm16, "orientations": {"pelvis": [0, 0, 0, 1], "head": None}}
        if all(list(v.iter_errors(b)) for b in bad_or) and not list(v.iter_errors(good_or)):
            passed += 1
            print("ok   landmark-frames schema takes a subset of orientations and rejects an unknown segment,"
                  " a 3-component quaternion and orientations beside frames")
        else:
            failed += 1
            print("FAIL landmark-frames schema: orientations accepted or rejected wrongly")
        bad = json.loads(json.dumps(reg_cases[0][1]))
        bad["surface_distance_mm"].pop("p95")
        bad2 = json.loads(json.dumps(reg_cases[0][1]))
        bad2["landmark_residuals_mm"]["per_landmark"]["head"] = -1.0
        v = validator("/mimic/schemas/register.schema.json")
        if list(v.iter_errors(bad)) and list(v.iter_errors(bad2)):
            passed += 1
            print("ok   register schema rejects a surface distance without p95 and a negative landmark residual")
        else:
            failed += 1
            print("FAIL register schema accepted a surface distance without p95 or a negative landmark residual")
        bad = dict(sampled_cases[0][1], ids=[0])
        if list(validator("/mimic/schemas/pairs-templates.schema.json").iter_errors(bad)):
            passed += 1
            print("ok   pairs-templates schema rejects a template id of 0")
        else:
            failed += 1
            print("FAIL pairs-templates schema accepted a template id of 0")
        # list: a template registered from another connectivity carries its
        # figures (none of synth's is registered: the key is absent)
        listed = json.loads(run("list", "--store", store, "--json"))
        registered = json.loads(json.dumps(listed))
        registered[0]["registration"] = {"mean_mm": 0.41, "p95_mm": 1.12, "max_mm": 3.5, "landmark_mean_mm": 2.25, "iterations": 24,
                                         "source_vertices": 6890}
        if not any("registration" in t for t in listed) and \
                not list(validator("/mimic/schemas/list.schema.json").iter_errors(registered)):
            passed += 1
            print("ok   list schema: no registration for synth's templates, one with its figures accepted")
        else:
            failed += 1
            print("FAIL list schema: a registration where none was made, or a valid one rejected")
        del registered[0]["registration"]["p95_mm"]
        if list(validator("/mimic/schemas/list.schema.json").iter_errors(registered)):
            passed += 1
            print("ok   list schema rejects a registration without p95_mm")
        else:
            failed += 1
            print("FAIL list schema accepted a registration without p95_mm")
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
