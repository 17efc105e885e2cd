/* BVH motion (Biovision hierarchy): HIERARCHY of ROOT/JOINT blocks with
 * OFFSET and CHANNELS, then MOTION with "Frames:", "Frame Time:" and one
 * line of channel values per frame. A joint's rotation is the product of its
 * rotation channels in the order listed (R = R_1 R_2 R_3), in degrees.
 * Position channels (Xposition gives x, whatever their order) are a
 * translation added to the joint's OFFSET in that frame: the root's is its
 * place in the world; BVH allows them on any joint and they are applied the
 * same way there. The orientation reader (mim_vest_motion_*) ignores them (a
 * vest gives no translation); the joint-position reader
 * (mim_vest_joint_motion_*) keeps them. Both go through mim__bvh_parse. */
#include "motion_internal.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const char *p, *end, *origin;
    int line;
    char tok[128];
    mim_error_t *err;
} lex_t;

/* Next whitespace-separated token into lx->tok; 0 at the end of text. */
static int next(lex_t *lx)
{
    while (lx->p < lx->end && isspace((unsigned char)*lx->p)) {
        if (*lx->p == '\n') lx->line++;
        lx->p++;
    }
    if (lx->p >= lx->end) return 0;
    size_t n = 0;
    while (lx->p < lx->end && !isspace((unsigned char)*lx->p)) {
        if (n + 1 < sizeof lx->tok) lx->tok[n++] = *lx->p;
        lx->p++;
    }
    lx->tok[n] = 0;
    return 1;
}

static int expect(lex_t *lx, const char *what)
{
    if (!next(lx)) return mim_error_set(lx->err, MIM_ETRUNCATED, "%s:%d: ends before '%s'", lx->origin, lx->line, what);
    if (strcmp(lx->tok, what))
        return mim_error_set(lx->err, MIM_EFORMAT, "%s:%d: expected '%s', found '%s'", lx->origin, lx->line, what,
                             lx->tok);
    return 0;
}

static int number(lex_t *lx, double *v)
{
    if (!next(lx)) return mim_error_set(lx->err, MIM_ETRUNCATED, "%s:%d: ends before a number", lx->origin, lx->line);
    char *e;
    errno = 0;
    *v = strtod(lx->tok, &e);
    if (*e || e == lx->tok || !isfinite(*v))
        return mim_error_set(lx->err, MIM_EFORMAT, "%s:%d: '%s' is not a finite number", lx->origin, lx->line,
                             lx->tok);
    return 0;
}

typedef struct {
    mim__mjoint_t *j;
    uint8_t nch[MIM__MOTION_MAX_JOINTS];
    int8_t ch[MIM__MOTION_MAX_JOINTS][6]; /* 0..2 position X Y Z, 3..5 rotation X Y Z */
    uint32_t first[MIM__MOTION_MAX_JOINTS];
    uint32_t n, channels;
} hier_t;

static int joint_block(lex_t *lx, hier_t *h, int parent, mim_vec3 base, int depth);

static int end_site(lex_t *lx)
{
    double v;
    int rc;
    if ((rc = expect(lx, "Site")) || (rc = expect(lx, "{")) || (rc = expect(lx, "OFFSET"))) return rc;
    for (int k = 0; k < 3; k++)
        if ((rc = number(lx, &v))) return rc;
    return expect(lx, "}");
}

static int joint_block(lex_t *lx, hier_t *h, int parent, mim_vec3 base, int depth)
{
    int rc;
    if (depth > 256) return mim_error_set(lx->err, MIM_EFORMAT, "%s:%d: joints nested too deeply", lx->origin, lx->line);
    if (h->n >= MIM__MOTION_MAX_JOINTS)
        return mim_error_set(lx->err, MIM_EFORMAT, "%s:%d: more than %u joints", lx->origin, lx->line,
                             MIM__MOTION_MAX_JOINTS);
    if (!next(lx)) return mim_error_set(lx->err, MIM_ETRUNCATED, "%s:%d: joint without a name", lx->origin, lx->line);
    uint32_t me = h->n++;
    mim__mjoint_t *J = &h->j[me];
    snprintf(J->name, sizeof J->name, "%.63s", lx->tok);
    J->parent = parent;
    if ((rc = expect(lx, "{")) || (rc = expect(lx, "OFFSET"))) return rc;
    double o[3];
    for (int k = 0; k < 3; k++)
        if ((rc = number(lx, &o[k]))) return rc;
    J->offset = mim_v3(o[0], o[1], o[2]);
    J->rest = mim_v3_add(base, J->offset);
    if ((rc = expect(lx, "CHANNELS"))) return rc;
    double nc;
    if ((rc = number(lx, &nc))) return rc;
    if (nc < 0 || nc > 6 || nc != floor(nc))
        return mim_error_set(lx->err, MIM_EFORMAT, "%s:%d: %g channels (0..6)", lx->origin, lx->line, nc);
    h->nch[me] = (uint8_t)nc;
    h->first[me] = h->channels;
    h->channels += (uint32_t)nc;
    static const char *const names[6] = {"Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation"};
    for (int c = 0; c < (int)nc; c++) {
        if (!next(lx)) return mim_error_set(lx->err, MIM_ETRUNCATED, "%s:%d: channels end early", lx->origin, lx->line);
        h->ch[me][c] = -1;
        for (int k = 0; k < 6; k++)
            if (!strcmp(lx->tok, names[k])) h->ch[me][c] = (int8_t)k;
        if (h->ch[me][c] < 0)
            return mim_error_set(lx->err, MIM_EFORMAT, "%s:%d: unknown channel '%s'", lx->origin, lx->line, lx->tok);
    }
    for (;;) {
        if (!next(lx)) return mim_error_set(lx->err, MIM_ETRUNCATED, "%s:%d: joint '%s' not closed", lx->origin, lx->line, J->name);
        if (!strcmp(lx->tok, "}")) return 0;
        if (!strcmp(lx->tok, "JOINT")) {
            if ((rc = joint_block(lx, h, (int)me, h->j[me].rest, depth + 1))) return rc;
        } else if (!strcmp(lx->tok, "End")) {
            if ((rc = end_site(lx))) return rc;
        } else {
            return mim_error_set(lx->err, MIM_EFORMAT, "%s:%d: unexpected '%s' in joint '%s'", lx->origin, lx->line,
                                 lx->tok, J->name);
        }
    }
}

int mim__bvh_parse(mim__motion_src_t *src, const char *text, size_t len, const char *origin, int translations,
                   mim_error_t *err)
{
    memset(src, 0, sizeof *src);
    /* text may be NULL with len 0: no arithmetic on a null pointer */
    lex_t lx = {text, text ? text + len : text, origin ? origin : "bvh", 1, {0}, err};
    hier_t *h = calloc(1, sizeof *h);
    if (h) h->j = calloc(MIM__MOTION_MAX_JOINTS, sizeof *h->j);
    double *vals = NULL;
    int rc = 0;
    if (!h || !h->j) {
        rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory", lx.origin);
        goto done;
    }
    if ((rc = expect(&lx, "HIERARCHY")) || (rc = expect(&lx, "ROOT"))) goto done;
    if ((rc = joint_block(&lx, h, -1, mim_v3(0, 0, 0), 0))) goto done;
    if ((rc = expect(&lx, "MOTION")) || (rc = expect(&lx, "Frames:"))) goto done;
    double nf, ft;
    if ((rc = number(&lx, &nf))) goto done;
    if ((rc = expect(&lx, "Frame")) || (rc = expect(&lx, "Time:")) || (rc = number(&lx, &ft))) goto done;
    if (nf < 1 || nf != floor(nf) || nf * h->n > (double)MIM__MOTION_MAX_VALUES || !(ft > 0)) {
        rc = mim_error_set(err, MIM_EFORMAT, "%s:%d: %g frames of %g s", lx.origin, lx.line, nf, ft);
        goto done;
    }
    src->n_joints = h->n, src->n_frames = (uint32_t)nf, src->frame_time = ft;
    src->joint = h->j, h->j = NULL;
    size_t nv = (size_t)src->n_frames * h->n;
    src->local = malloc(sizeof *src->local * nv);
    if (translations) src->trans = malloc(sizeof *src->trans * nv);
    vals = malloc(sizeof *vals * (h->channels ? h->channels : 1));
    if (!src->local || (translations && !src->trans) || !vals) {
        rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory for %u frames", lx.origin, src->n_frames);
        goto done;
    }
    for (uint32_t f = 0; f < src->n_frames && !rc; f++) {
        for (uint32_t c = 0; c < h->channels && !rc; c++) rc = number(&lx, &vals[c]);
        for (uint32_t j = 0; j < h->n && !rc; j++) {
            mim_quat q = mim_quat_identity();
            double t[3] = {0, 0, 0};
            for (int c = 0; c < h->nch[j]; c++) {
                int k = h->ch[j][c];
                double v = vals[h->first[j] + c];
                if (k >= 3) q = mim_quat_mul(q, mim__axis_rot(k - 3, v));
                else t[k] = v; /* Xposition gives x, wherever it is listed */
            }
            src->local[(size_t)f * h->n + j] = q;
            if (src->trans) src->trans[(size_t)f * h->n + j] = mim_v3(t[0], t[1], t[2]);
        }
    }
done:
    free(vals);
    if (rc) mim__motion_src_free(src);
    if (h) free(h->j);
    free(h);
    return rc;
}

int mim_vest_motion_parse_bvh(mim_vest_motion_t *m, const char *text, size_t len, const char *origin,
                              mim_error_t *err)
{
    if (!m || (!text && len)) return mim_error_set(err, MIM_EINVAL, "bvh: bad arguments");
    memset(m, 0, sizeof *m);
    if (!origin) origin = "bvh";
    mim__motion_src_t src;
    int rc = mim__bvh_parse(&src, text, len, origin, 0, err);
    if (!rc) rc = mim__motion_build(m, &src, origin, err);
    mim__motion_src_free(&src);
    return rc;
}

int mim_vest_motion_read_bvh(mim_vest_motion_t *m, const char *path, mim_error_t *err)
{
    char *text;
    size_t len;
    int rc = mim__read_text(path, &text, &len, err);
    if (rc) return rc;
    rc = mim_vest_motion_parse_bvh(m, text, len, path, err);
    free(text);
    return rc;
}

int mim_vest_joint_motion_parse_bvh(mim_vest_joint_motion_t *m, const char *text, size_t len, const char *origin,
                                    mim_error_t *err)
{
    if (m) memset(m, 0, sizeof *m);
    if (!m || (!text && len)) return mim_error_set(err, MIM_EINVAL, "bvh: bad arguments");
    if (!origin) origin = "bvh";
    mim__motion_src_t src;
    int rc = mim__bvh_parse(&src, text, len, origin, 1, err);
    if (!rc) rc = mim__joint_motion_build(m, &src, origin, err);
    mim__motion_src_free(&src);
    return rc;
}

int mim_vest_joint_motion_read_bvh(mim_vest_joint_motion_t *m, const char *path, mim_error_t *err)
{
    if (m) memset(m, 0, sizeof *m);
    if (!m || !path) return mim_error_set(err, MIM_EINVAL, "bvh: bad arguments");
    char *text;
    size_t len;
    int rc = mim__read_text(path, &text, &len, err);
    if (rc) return rc;
    rc = mim_vest_joint_motion_parse_bvh(m, text, len, path, err);
    free(text);
    return rc;
}
