/* ASF skeleton + AMC motion (Acclaim; the CMU motion capture database).
 * ASF bones carry a direction, a length, an `axis` (the bone's local frame as
 * Euler angles with an order) and their degrees of freedom; :hierarchy links
 * them. An AMC frame gives each bone's dof values. A bone's rotation relative
 * to its parent, in the rest frame, is C M C^-1 with C from `axis` and M
 * from the dofs, both composed so the first listed axis turns first
 * (order XYZ -> Rz Ry Rx), as in the CMU reference viewer. tx/ty/tz dofs
 * (the root's place in the world) are a translation added to the bone's
 * offset; the orientation reader ignores them, the joint-position reader
 * keeps them. Both go through mim__amc_read. */
#include "motion_internal.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

typedef struct {
    char name[64];
    mim_vec3 dir;
    double length;
    mim_quat C;
    int ndof;
    int dof[6]; /* 0..2 rx ry rz, 3..5 tx ty tz, 6 l (ignored) */
    int parent;
} bone_t;

typedef struct {
    bone_t *b;
    uint32_t n;
    double angle_scale; /* to degrees */
    mim_vec3 root_pos;  /* :root position */
    int bad_pos_line;   /* line of an unreadable :root position (only joint positions need it), 0 if none */
} asf_t;

static int axis_of(char c) { return c == 'X' || c == 'x' ? 0 : c == 'Y' || c == 'y' ? 1 : c == 'Z' || c == 'z' ? 2 : -1; }

/* Euler angles in degrees, first listed axis turning first. */
static mim_quat euler(const double a[3], const int ax[3])
{
    mim_quat q = mim_quat_identity();
    for (int k = 0; k < 3; k++) q = mim_quat_mul(mim__axis_rot(ax[k], a[k]), q);
    return q;
}

static int find_bone(const asf_t *s, const char *name)
{
    for (uint32_t i = 0; i < s->n; i++)
        if (!strcasecmp(s->b[i].name, name)) return (int)i;
    return -1;
}

/* Splits a line into at most 16 tokens (in place). */
static int split(char *line, char **tok)
{
    int n = 0;
    for (char *p = line; *p && n < 16;) {
        while (*p && isspace((unsigned char)*p)) p++;
        if (!*p) break;
        tok[n++] = p;
        while (*p && !isspace((unsigned char)*p)) p++;
        if (*p) *p++ = 0;
    }
    return n;
}

static int num(const char *t, double *v)
{
    char *e;
    *v = strtod(t, &e);
    return *e || e == t || !isfinite(*v) ? -1 : 0;
}

static int parse_dofs(bone_t *b, char **tok, int n)
{
    b->ndof = 0;
    for (int i = 1; i < n && b->ndof < 6; i++) {
        const char *t = tok[i];
        int d = -1;
        if ((t[0] == 'r' || t[0] == 'R') && t[1] && !t[2] && axis_of(t[1]) >= 0) d = axis_of(t[1]);
        else if ((t[0] == 't' || t[0] == 'T') && t[1] && !t[2] && axis_of(t[1]) >= 0) d = 3 + axis_of(t[1]);
        else if (!strcasecmp(t, "l")) d = 6;
        else return -1;
        b->dof[b->ndof++] = d;
    }
    return 0;
}

static int parse_asf(asf_t *s, char *text, const char *path, mim_error_t *err)
{
    s->angle_scale = 1;
    s->b = calloc(MIM__MOTION_MAX_JOINTS, sizeof *s->b);
    if (!s->b) return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", path);
    /* bone 0 is the root */
    s->n = 1;
    snprintf(s->b[0].name, sizeof s->b[0].name, "root");
    s->b[0].C = mim_quat_identity();
    s->b[0].parent = -1;
    static const int root_dof[6] = {3, 4, 5, 0, 1, 2};
    memcpy(s->b[0].dof, root_dof, sizeof root_dof);
    s->b[0].ndof = 6;
    char section[32] = "";
    bone_t *cur = NULL;
    int ln = 0;
    for (char *line = text, *nl; line && *line; line = nl) {
        nl = strchr(line, '\n');
        if (nl) *nl++ = 0;
        ln++;
        char *tok[16];
        int n = split(line, tok);
        if (!n || tok[0][0] == '#') continue;
        if (tok[0][0] == ':') {
            snprintf(section, sizeof section, "%s", tok[0]);
            if (!strcmp(section, ":root")) cur = &s->b[0];
            continue;
        }
        if (!strcmp(section, ":units") && n >= 2 && !strcmp(tok[0], "angle"))
            s->angle_scale = !strcasecmp(tok[1], "rad") ? 180.0 / M_PI : 1;
        else if (!strcmp(section, ":root")) {
            if (!strcmp(tok[0], "order") && parse_dofs(cur, tok, n))
                return mim_error_set(err, MIM_EFORMAT, "%s:%d: bad root order", path, ln);
            if (!strcmp(tok[0], "orientation") && n >= 4) {
                double a[3];
                static const int xyz[3] = {0, 1, 2};
                if (num(tok[1], &a[0]) || num(tok[2], &a[1]) || num(tok[3], &a[2]))
                    return mim_error_set(err, MIM_EFORMAT, "%s:%d: bad root orientation", path, ln);
                cur->C = euler(a, xyz);
            }
            if (!strcmp(tok[0], "position") && n >= 4) {
                double a[3];
                if (num(tok[1], &a[0]) || num(tok[2], &a[1]) || num(tok[3], &a[2])) s->bad_pos_line = ln;
                else s->root_pos = mim_v3(a[0], a[1], a[2]);
            }
        } else if (!strcmp(section, ":bonedata")) {
            if (!strcmp(tok[0], "begin")) {
                if (s->n >= MIM__MOTION_MAX_JOINTS)
                    return mim_error_set(err, MIM_EFORMAT, "%s:%d: too many bones", path, ln);
                cur = &s->b[s->n++];
                cur->C = mim_quat_identity();
                cur->parent = -2;
            } else if (!strcmp(tok[0], "end")) {
                cur = NULL;
            } else if (!cur) {
                return mim_error_set(err, MIM_EFORMAT, "%s:%d: '%s' outside begin/end", path, ln, tok[0]);
            } else if (!strcmp(tok[0], "name") && n >= 2) {
                snprintf(cur->name, sizeof cur->name, "%s", tok[1]);
            } else if (!strcmp(tok[0], "direction") && n >= 4) {
                double a[3];
                if (num(tok[1], &a[0]) || num(tok[2], &a[1]) || num(tok[3], &a[2]))
                    return mim_error_set(err, MIM_EFORMAT, "%s:%d: bad direction", path, ln);
                cur->dir = mim_v3(a[0], a[1], a[2]);
            } else if (!strcmp(tok[0], "length") && n >= 2) {
                if (num(tok[1], &cur->length)) return mim_error_set(err, MIM_EFORMAT, "%s:%d: bad length", path, ln);
            } else if (!strcmp(tok[0], "axis") && n >= 5) {
                double a[3];
                int ax[3];
                for (int k = 0; k < 3; k++) ax[k] = axis_of(tok[4][k]);
                if (num(tok[1], &a[0]) || num(tok[2], &a[1]) || num(tok[3], &a[2]) || strlen(tok[4]) != 3 ||
                    ax[0] < 0 || ax[1] < 0 || ax[2] < 0)
                    return mim_error_set(err, MIM_EFORMAT, "%s:%d: bad axis", path, ln);
                for (int k = 0; k < 3; k++) a[k] *= s->angle_scale;
                cur->C = euler(a, ax);
            } else if (!strcmp(tok[0], "dof")) {
                if (parse_dofs(cur, tok, n)) return mim_error_set(err, MIM_EFORMAT, "%s:%d: bad dof", path, ln);
            }
        } else if (!strcmp(section, ":hierarchy")) {
            if (!strcmp(tok[0], "begin") || !strcmp(tok[0], "end")) continue;
            int p = find_bone(s, tok[0]);
            if (p < 0) return mim_error_set(err, MIM_EFORMAT, "%s:%d: unknown bone '%s'", path, ln, tok[0]);
            for (int i = 1; i < n; i++) {
                int c = find_bone(s, tok[i]);
                if (c <= 0 || s->b[c].parent != -2)
                    return mim_error_set(err, MIM_EFORMAT, "%s:%d: bad child '%s'", path, ln, tok[i]);
                s->b[c].parent = p;
            }
        }
    }
    return 0;
}

int mim__amc_read(mim__motion_src_t *src_out, const char *asf_path, const char *amc_path, int translations,
                  mim_error_t *err)
{
    memset(src_out, 0, sizeof *src_out);
    char *asf_text = NULL, *amc_text = NULL;
    size_t len;
    asf_t s = {0};
    mim__motion_src_t src = {0};
    uint32_t *order = NULL;
    int rc = mim__read_text(asf_path, &asf_text, &len, err);
    if (!rc) rc = parse_asf(&s, asf_text, asf_path, err);
    if (!rc && translations && s.bad_pos_line)
        rc = mim_error_set(err, MIM_EFORMAT, "%s:%d: bad root position", asf_path, s.bad_pos_line);
    if (!rc) rc = mim__read_text(amc_path, &amc_text, &len, err);
    if (rc) goto done;
    /* order bones parents-first; bones outside the hierarchy are left out */
    order = malloc(sizeof *order * s.n);
    int *pos = malloc(sizeof *pos * s.n);
    src.joint = calloc(s.n, sizeof *src.joint);
    if (!order || !pos || !src.joint) {
        free(pos);
        rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory", asf_path);
        goto done;
    }
    for (uint32_t i = 0; i < s.n; i++) pos[i] = -1;
    uint32_t k = 0;
    order[k] = 0, pos[0] = 0, k++;
    for (int changed = 1; changed;) {
        changed = 0;
        for (uint32_t i = 1; i < s.n; i++)
            if (pos[i] < 0 && s.b[i].parent >= 0 && pos[s.b[i].parent] >= 0)
                pos[i] = (int)k, order[k++] = i, changed = 1;
    }
    src.n_joints = k;
    for (uint32_t j = 0; j < k; j++) {
        const bone_t *b = &s.b[order[j]];
        snprintf(src.joint[j].name, sizeof src.joint[j].name, "%s", b->name);
        src.joint[j].parent = b->parent >= 0 ? pos[b->parent] : -1;
        /* a bone starts where its parent ends */
        src.joint[j].offset =
            b->parent >= 0 ? mim_v3_scale(s.b[b->parent].dir, s.b[b->parent].length) : s.root_pos;
        src.joint[j].rest = b->parent >= 0 ? mim_v3_add(src.joint[src.joint[j].parent].rest, src.joint[j].offset)
                                           : src.joint[j].offset;
    }
    /* frames: a line with one integer starts a frame */
    uint32_t cap = 256, nf = 0;
    src.local = malloc(sizeof *src.local * cap * k);
    if (translations) src.trans = malloc(sizeof *src.trans * cap * k);
    if (!src.local || (translations && !src.trans)) {
        free(pos);
        rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory", amc_path);
        goto done;
    }
    int ln = 0;
    for (char *line = amc_text, *nl; line && *line && !rc; line = nl) {
        nl = strchr(line, '\n');
        if (nl) *nl++ = 0;
        ln++;
        char *tok[16];
        int n = split(line, tok);
        if (!n || tok[0][0] == '#' || tok[0][0] == ':') continue;
        if (n == 1 && isdigit((unsigned char)tok[0][0])) {
            if (nf == cap) {
                if ((uint64_t)cap * 2 * k > MIM__MOTION_MAX_VALUES) {
                    rc = mim_error_set(err, MIM_EFORMAT, "%s:%d: too many frames", amc_path, ln);
                    break;
                }
                mim_quat *nq = realloc(src.local, sizeof *nq * (size_t)(cap *= 2) * k);
                if (!nq) {
                    rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory", amc_path);
                    break;
                }
                src.local = nq;
                if (translations) {
                    mim_vec3 *nt = realloc(src.trans, sizeof *nt * (size_t)cap * k);
                    if (!nt) {
                        rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory", amc_path);
                        break;
                    }
                    src.trans = nt;
                }
            }
            for (uint32_t j = 0; j < k; j++) src.local[(size_t)nf * k + j] = mim_quat_identity();
            if (src.trans)
                for (uint32_t j = 0; j < k; j++) src.trans[(size_t)nf * k + j] = mim_v3(0, 0, 0);
            nf++;
            continue;
        }
        if (!nf) {
            rc = mim_error_set(err, MIM_EFORMAT, "%s:%d: bone values before the first frame number", amc_path, ln);
            break;
        }
        int bi = find_bone(&s, tok[0]);
        if (bi < 0 || pos[bi] < 0) continue; /* bones the hierarchy leaves out */
        const bone_t *b = &s.b[bi];
        if (n - 1 != b->ndof) {
            rc = mim_error_set(err, MIM_EFORMAT, "%s:%d: bone '%s' has %d values, its dof lists %d", amc_path, ln,
                               tok[0], n - 1, b->ndof);
            break;
        }
        double a[3] = {0, 0, 0}, t[3] = {0, 0, 0};
        int ax[3], na = 0;
        for (int i = 0; i < b->ndof; i++) {
            double v;
            if (num(tok[1 + i], &v)) {
                rc = mim_error_set(err, MIM_EFORMAT, "%s:%d: '%s' is not a number", amc_path, ln, tok[1 + i]);
                break;
            }
            if (b->dof[i] < 3 && na < 3) a[na] = v * s.angle_scale, ax[na++] = b->dof[i];
            else if (b->dof[i] >= 3 && b->dof[i] < 6) t[b->dof[i] - 3] = v; /* tx gives x, wherever listed */
        }
        if (rc) break;
        for (int i = na; i < 3; i++) a[i] = 0, ax[i] = 0;
        mim_quat M = euler(a, ax), Ci = {-b->C.x, -b->C.y, -b->C.z, b->C.w};
        src.local[(size_t)(nf - 1) * k + (uint32_t)pos[bi]] = mim_quat_mul(mim_quat_mul(b->C, M), Ci);
        if (src.trans) src.trans[(size_t)(nf - 1) * k + (uint32_t)pos[bi]] = mim_v3(t[0], t[1], t[2]);
    }
    free(pos);
    if (rc) goto done;
    src.n_frames = nf;
    src.frame_time = 1.0 / 120; /* CMU captures at 120 Hz; AMC does not say */
    *src_out = src, src = (mim__motion_src_t){0};
done:
    mim__motion_src_free(&src);
    free(order), free(s.b), free(asf_text), free(amc_text);
    return rc;
}

int mim_vest_motion_read_amc(mim_vest_motion_t *m, const char *asf_path, const char *amc_path, mim_error_t *err)
{
    memset(m, 0, sizeof *m);
    mim__motion_src_t src;
    int rc = mim__amc_read(&src, asf_path, amc_path, 0, err);
    if (!rc) rc = mim__motion_build(m, &src, amc_path, err);
    mim__motion_src_free(&src);
    return rc;
}

int mim_vest_joint_motion_read_amc(mim_vest_joint_motion_t *m, const char *asf_path, const char *amc_path,
                                   mim_error_t *err)
{
    if (m) memset(m, 0, sizeof *m);
    if (!m || !asf_path || !amc_path) return mim_error_set(err, MIM_EINVAL, "amc: bad arguments");
    mim__motion_src_t src;
    int rc = mim__amc_read(&src, asf_path, amc_path, 1, err);
    if (!rc) rc = mim__joint_motion_build(m, &src, amc_path, err);
    mim__motion_src_free(&src);
    return rc;
}
