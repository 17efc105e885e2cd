#!/usr/bin/env python3
"""bench/relative_accuracy.py: relative transfer (issue 15)'s accuracy through the CLI (mimic transfer --landmarks,
the index's own nearest template), strict leave one subject out.

For each held-out subject A: a store of every other subject (files linked,
labels from the names), indexed; for each pose p >= 1 of A: the avatar is A's
rest mesh (a file), the landmarks A's true ones in p; `mimic transfer
--relative on|off --json`; the error is the per-vertex distance to A's true p.

usage: bench/relative_accuracy.py MIMIC DATASET_DIR WORK_DIR [--subjects N]
Prints a Markdown table (mean, p95 in mm; relative used; frames turned)."""
import json, math, os, re, shutil, struct, subprocess, sys


def read_ply(path):
    d = open(path, 'rb').read()
    h = d.index(b'end_header\n') + 11
    hdr = d[:h].decode()
    n = int(re.search(r'element vertex (\d+)', hdr).group(1))
    if 'ascii' in hdr:
        lines = d[h:].decode().split('\n')
        return [tuple(map(float, lines[i].split()[:3])) for i in range(n)]
    props = re.findall(r'element vertex \d+\n((?:property \w+ \w+\n)+)', hdr)[0].count('property')
    return [struct.unpack_from('<3f', d, h + 4 * props * i) for i in range(n)]


def main():
    mimic, data, work = sys.argv[1:4]
    nsub = int(sys.argv[sys.argv.index('--subjects') + 1]) if '--subjects' in sys.argv else None
    files = sorted(f for f in os.listdir(data) if re.match(r'.*_s\d+_p\d+\.ply$', f))
    subj = lambda f: int(re.search(r'_s(\d+)_p', f).group(1))
    pose = lambda f: int(re.search(r'_p(\d+)\.ply', f).group(1))
    subjects = sorted({subj(f) for f in files})[:nsub]
    lm = json.load(open(os.path.join(data, 'landmarks.json')))
    verts = [e['vertex'] if isinstance(e, dict) else e for e in (lm['landmarks'] if 'landmarks' in lm else lm)]
    os.makedirs(work, exist_ok=True)
    err = {'off': [], 'on': []}
    used = turned = runs = 0
    for a in subjects:
        bd, st = os.path.join(work, 'b%d' % a), os.path.join(work, 's%d' % a)
        shutil.rmtree(bd, ignore_errors=True), shutil.rmtree(st, ignore_errors=True)
        os.makedirs(bd)
        os.symlink(os.path.join(data, 'landmarks.json'), os.path.join(bd, 'landmarks.json'))
        for f in files:
            if subj(f) != a and subj(f) in subjects:
                os.symlink(os.path.join(data, f), os.path.join(bd, f))
        subprocess.run([mimic, 'ingest', '--store', st, bd], check=True, capture_output=True)
        subprocess.run([mimic, 'index', '--store', st], check=True, capture_output=True)
        rest = [f for f in files if subj(f) == a and pose(f) == 0][0]
        for f in files:
            if subj(f) != a or pose(f) == 0:
                continue
            truth = read_ply(os.path.join(data, f))
            lmf = os.path.join(work, 'lm.json')
            json.dump({'landmarks': [list(truth[v]) for v in verts]}, open(lmf, 'w'))
            for mode in ('off', 'on'):
                out = os.path.join(work, 'out.ply')
                r = subprocess.run([mimic, 'transfer', '--store', st, '--avatar', os.path.join(data, rest),
                                    '--landmarks', lmf, '--relative', mode, '--json', '-o', out],
                                   check=True, capture_output=True, text=True)
                rep = json.loads(r.stdout)
                got = read_ply(out)
                err[mode] += [math.dist(x, y) * 1e3 for x, y in zip(got, truth)]
                if mode == 'on':
                    runs += 1
                    used += rep['relative']
                    turned += rep['frames_turned']
        print('subject %d done' % a, file=sys.stderr)
    print('| %s | relative | mean mm | p95 mm |' % os.path.basename(data.rstrip('/')))
    print('|---|---|---:|---:|')
    for mode in ('off', 'on'):
        e = sorted(err[mode])
        print('| %d subjects | %s | %.2f | %.2f |' % (len(subjects), mode, sum(e) / len(e), e[int(0.95 * (len(e) - 1))]))
    print('\nrelative used in %d of %d transfers, frames turned in %d' % (used, runs, turned))


main()
