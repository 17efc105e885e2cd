/* Writing a dataset: one binary PLY per body, manifest.csv, landmarks.json.
 *
 * Every file is written under a temporary name in the same folder and then
 * renamed, so readers (and a run killed half-way) never see a partial file.
 * The manifest and landmark map come last: their presence means the bodies
 * they list are all there. Bytes are packed explicitly little-endian so the
 * files are identical on any host. */
#include "synth_internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>

static int mkdirs(const char *dir, mim_error_t *err)
{
    size_t n = strlen(dir);
    char *p = malloc(n + 1);
    if (!p) return mim_error_set(err, MIM_ENOMEM, "synth: out of memory");
    memcpy(p, dir, n + 1);
    for (size_t i = 1; i <= n; i++) {
        if (p[i] != '/' && p[i] != '\0') continue;
        char c = p[i];
        p[i] = '\0';
        if (mkdir(p, 0777) != 0 && errno != EEXIST) {
            int e = errno;
            int rc = mim_error_set(err, -e, "%s: cannot create folder: %s", p, strerror(e));
            free(p);
            return rc;
        }
        p[i] = c;
    }
    free(p);
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        return mim_error_set(err, -ENOTDIR, "%s: not a folder", dir);
    return 0;
}

static void put_u32(uint8_t *b, uint32_t v)
{
    b[0] = (uint8_t)v, b[1] = (uint8_t)(v >> 8), b[2] = (uint8_t)(v >> 16), b[3] = (uint8_t)(v >> 24);
}

static void put_f32(uint8_t *b, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    put_u32(b, u);
}

static char *join(const char *dir, const char *name)
{
    size_t n = strlen(dir) + strlen(name) + 2;
    char *p = malloc(n);
    if (p) snprintf(p, n, "%s/%s", dir, name);
    return p;
}

/* Writes len bytes of each block to dir/name through dir/.name.tmp. */
static int write_atomic(const char *dir, const char *name, const void *const *blocks, const size_t *lens,
                        int nblocks, mim_error_t *err)
{
    char tmpname[300];
    snprintf(tmpname, sizeof tmpname, ".%s.tmp", name);
    char *path = join(dir, name), *tmp = join(dir, tmpname);
    int rc = 0;
    if (!path || !tmp) {
        rc = mim_error_set(err, MIM_ENOMEM, "synth: out of memory");
        goto out;
    }
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        int e = errno;
        rc = mim_error_set(err, -e, "%s: cannot write: %s", tmp, strerror(e));
        goto out;
    }
    int ok = 1;
    for (int i = 0; i < nblocks && ok; i++) ok = fwrite(blocks[i], 1, lens[i], f) == lens[i];
    int e = ok ? 0 : errno;
    if (fclose(f) != 0 && ok) ok = 0, e = errno;
    if (!ok) {
        remove(tmp);
        rc = mim_error_set(err, -(e ? e : EIO), "%s: write failed: %s", tmp, strerror(e ? e : EIO));
        goto out;
    }
    if (rename(tmp, path) != 0) {
        e = errno;
        remove(tmp);
        rc = mim_error_set(err, -e, "%s: cannot rename to %s: %s", tmp, path, strerror(e));
    }
out:
    free(path), free(tmp);
    return rc;
}

int mim_synth_write_dataset(const mim_synth_t *s, const char *dir, mim_error_t *err)
{
    if (!s || !dir || !*dir) return mim_error_set(err, MIM_EINVAL, "synth: no output folder");
    int rc = mkdirs(dir, err);
    if (rc) return rc;
    uint32_t nv = s->nv, nf = s->nf, S = s->opt.subjects, P = s->opt.poses;
    char header[256];
    int hl = snprintf(header, sizeof header,
                      "ply\nformat binary_little_endian 1.0\ncomment mimic synth seed=%llu\n"
                      "element vertex %u\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face %u\nproperty list uchar int vertex_indices\nend_header\n",
                      (unsigned long long)s->opt.seed, nv, nf);
    size_t vbytes = (size_t)nv * 12, fbytes = (size_t)nf * 13;
    uint8_t *vbuf = malloc(vbytes), *fbuf = malloc(fbytes);
    float *pos = malloc((size_t)nv * 3 * sizeof *pos);
    double *work = malloc((size_t)nv * 3 * sizeof *work);
    char *mtmp = join(dir, ".manifest.csv.tmp"), *mpath = join(dir, "manifest.csv");
    FILE *man = NULL;
    if (!vbuf || !fbuf || !pos || !work || !mtmp || !mpath) {
        rc = mim_error_set(err, MIM_ENOMEM, "synth: out of memory");
        goto out;
    }
    /* the manifest grows alongside the bodies and is renamed in last */
    man = fopen(mtmp, "wb");
    if (!man) {
        int e = errno;
        rc = mim_error_set(err, -e, "%s: cannot write: %s", mtmp, strerror(e));
        goto out;
    }
    fputs("file,subject,pose,pose_name\n", man);
    for (uint32_t f = 0; f < nf; f++) { /* the face block is the same in every file */
        uint8_t *b = fbuf + 13 * (size_t)f;
        b[0] = 3;
        for (int k = 0; k < 3; k++) put_u32(b + 1 + 4 * k, s->faces[3 * f + k]);
    }
    mim_progress_t pr;
    mim_progress_begin(&pr, "synth", (uint64_t)S * P);
    for (uint32_t si = 0; si < S && !rc; si++) {
        mim__subject_t sub;
        mim__subject_make(&sub, s->opt.seed, si);
        mim__body_t b;
        rc = mim__body_eval(s, &sub, &b);
        if (rc) {
            mim_error_set(err, rc, "synth: subject %u: %s", si, mim_strerror(rc));
            break;
        }
        for (uint32_t p = 0; p < P && !rc; p++) {
            mim__body_pose(s, &b, p, work, pos, NULL);
            for (uint32_t i = 0; i < 3 * nv; i++) put_f32(vbuf + 4 * (size_t)i, pos[i]);
            char name[64];
            mim_synth_file_name(si, p, name, sizeof name);
            const void *blocks[3] = {header, vbuf, fbuf};
            size_t lens[3] = {(size_t)hl, vbytes, fbytes};
            rc = write_atomic(dir, name, blocks, lens, 3, err);
            fprintf(man, "%s,%u,%u,%s\n", name, si, p, s->pose_name[p]);
            mim_progress_update(&pr, (uint64_t)si * P + p + 1);
        }
        mim__body_free(&b);
    }
    mim_progress_end(&pr);
    {
        int bad = ferror(man), e = errno;
        if (fclose(man) != 0 && !bad) bad = 1, e = errno;
        man = NULL;
        if (!rc && bad) rc = mim_error_set(err, -(e ? e : EIO), "%s: write failed: %s", mtmp, strerror(e ? e : EIO));
    }
    if (rc) {
        remove(mtmp);
        goto out;
    }
    if (rename(mtmp, mpath) != 0) {
        int e = errno;
        remove(mtmp);
        rc = mim_error_set(err, -e, "%s: cannot rename to %s: %s", mtmp, mpath, strerror(e));
        goto out;
    }
    {
        mim_landmark_map_t map;
        mim_synth_landmarks(s, &map);
        char *tmp = join(dir, ".landmarks.json.tmp"), *path = join(dir, "landmarks.json");
        if (!tmp || !path) rc = mim_error_set(err, MIM_ENOMEM, "synth: out of memory");
        else rc = mim_landmarks_write(&map, tmp, err);
        if (!rc && rename(tmp, path) != 0) {
            int e = errno;
            rc = mim_error_set(err, -e, "%s: cannot rename to %s: %s", tmp, path, strerror(e));
        }
        if (rc && tmp) remove(tmp);
        free(tmp), free(path);
    }
out:
    if (man) fclose(man), remove(mtmp);
    free(vbuf), free(fbuf), free(pos), free(work), free(mtmp), free(mpath);
    return rc;
}
