/* Realistic rigged glTF test avatars: rigged_avatar.h.
 *
 * Everything is built in the synth frame (metres, +Y up, facing +Z, own
 * left +X) from one synth body, its joints and landmarks; at the end VRM
 * 0.x models are turned 180 degrees about +Y (x, z negated: exact in
 * floats) and positions scaled to the file's unit. The GLB is written by
 * hand: JSON text, then the binary chunk (one bufferView per accessor,
 * each 4-byte aligned). */
#include "rigged_avatar.h"

#include "mim_core.h"
#include "mim_synth.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* clang-format off */
enum {
    J_PELVIS, J_SPINE, J_CHEST, J_NECK, J_HEAD, J_LCLAV, J_RCLAV, J_LUARM, J_RUARM, J_LFARM,
    J_RFARM, J_LHAND, J_RHAND, J_LTHIGH, J_RTHIGH, J_LSHIN, J_RSHIN, J_LFOOT, J_RFOOT, NJ
};

/* The synth skeleton this file is written for (checked against the synth). */
static const char *const synth_names[NJ] = {
    "pelvis",     "spine",      "chest",     "neck",      "head",   "l_clavicle", "r_clavicle",
    "l_upperarm", "r_upperarm", "l_forearm", "r_forearm", "l_hand", "r_hand",     "l_thigh",
    "r_thigh",    "l_shin",     "r_shin",    "l_foot",    "r_foot"};
static const char *const mixamo_names[NJ] = {
    "mixamorig:Hips",         "mixamorig:Spine",         "mixamorig:Spine2",       "mixamorig:Neck",
    "mixamorig:Head",         "mixamorig:LeftShoulder",  "mixamorig:RightShoulder", "mixamorig:LeftArm",
    "mixamorig:RightArm",     "mixamorig:LeftForeArm",   "mixamorig:RightForeArm", "mixamorig:LeftHand",
    "mixamorig:RightHand",    "mixamorig:LeftUpLeg",     "mixamorig:RightUpLeg",   "mixamorig:LeftLeg",
    "mixamorig:RightLeg",     "mixamorig:LeftFoot",      "mixamorig:RightFoot"};
static const char *const blender_names[NJ] = {
    "hips",       "spine",       "chest",     "neck",      "head",   "shoulder.L", "shoulder.R",
    "upper_arm.L", "upper_arm.R", "forearm.L", "forearm.R", "hand.L", "hand.R",     "thigh.L",
    "thigh.R",    "shin.L",      "shin.R",    "foot.L",    "foot.R"};
static const char *const vrm_bones[NJ] = {
    "hips",         "spine",         "chest",        "neck",         "head",      "leftShoulder", "rightShoulder",
    "leftUpperArm", "rightUpperArm", "leftLowerArm", "rightLowerArm", "leftHand", "rightHand",    "leftUpperLeg",
    "rightUpperLeg", "leftLowerLeg", "rightLowerLeg", "leftFoot",    "rightFoot"};
/* The bone of joint j runs to this child joint (-1: an end bone). */
static const int bone_child[NJ] = {J_SPINE, J_CHEST, J_NECK, J_HEAD, -1, J_LUARM, J_RUARM, J_LFARM, J_RFARM, J_LHAND,
                                   J_RHAND, -1, -1, J_LSHIN, J_RSHIN, J_LFOOT, J_RFOOT, -1, -1};
/* UV islands with split_seams: trunk, left arm, right arm, left leg, right leg. */
static const int bone_region[NJ] = {0, 0, 0, 0, 0, 0, 0, 1, 2, 1, 2, 1, 2, 3, 4, 3, 4, 3, 4};
/* clang-format on */

/* ---- small vector algebra (double) ---- */
typedef struct {
    double x, y, z;
} v3;
static v3 V(double x, double y, double z) { return (v3){x, y, z}; }
static v3 vadd(v3 a, v3 b) { return V(a.x + b.x, a.y + b.y, a.z + b.z); }
static v3 vsub(v3 a, v3 b) { return V(a.x - b.x, a.y - b.y, a.z - b.z); }
static v3 vscale(v3 a, double s) { return V(a.x * s, a.y * s, a.z * s); }
static double vdot(v3 a, v3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static v3 vcross(v3 a, v3 b) { return V(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x); }
static double vlen(v3 a) { return sqrt(vdot(a, a)); }
static v3 vnorm(v3 a)
{
    double l = vlen(a);
    return l > 0 ? vscale(a, 1 / l) : V(0, 1, 0);
}
static v3 vload(const float *p) { return V(p[0], p[1], p[2]); }
static void vstore(float *p, v3 a) { p[0] = (float)a.x, p[1] = (float)a.y, p[2] = (float)a.z; }

/* Rotates v by the unit quaternion q = (x, y, z, w). */
static v3 qrot(const double q[4], v3 v)
{
    v3 u = V(q[0], q[1], q[2]);
    v3 t = vscale(vcross(u, v), 2);
    return vadd(vadd(v, vscale(t, q[3])), vcross(u, t));
}

/* The unit quaternion of the rotation matrix with columns c0 c1 c2 (Shepperd). */
static void quat_of_axes(v3 c0, v3 c1, v3 c2, double q[4])
{
    double m00 = c0.x, m11 = c1.y, m22 = c2.z, tr = m00 + m11 + m22;
    if (tr > 0) {
        double s = 2 * sqrt(tr + 1);
        q[3] = s / 4, q[0] = (c1.z - c2.y) / s, q[1] = (c2.x - c0.z) / s, q[2] = (c0.y - c1.x) / s;
    } else if (m00 > m11 && m00 > m22) {
        double s = 2 * sqrt(1 + m00 - m11 - m22);
        q[3] = (c1.z - c2.y) / s, q[0] = s / 4, q[1] = (c1.x + c0.y) / s, q[2] = (c2.x + c0.z) / s;
    } else if (m11 > m22) {
        double s = 2 * sqrt(1 + m11 - m00 - m22);
        q[3] = (c2.x - c0.z) / s, q[0] = (c1.x + c0.y) / s, q[1] = s / 4, q[2] = (c2.y + c1.z) / s;
    } else {
        double s = 2 * sqrt(1 + m22 - m00 - m11);
        q[3] = (c0.y - c1.x) / s, q[0] = (c2.x + c0.z) / s, q[1] = (c2.y + c1.z) / s, q[2] = s / 4;
    }
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int i = 0; i < 4; i++) q[i] /= n;
}

/* ---- geometry under construction: welded positions, faces, a skin ---- */
typedef struct geo {
    float *pos;    /* 3 per vertex, metres */
    uint16_t *jnt; /* 4 per vertex */
    float *wgt;    /* 4 per vertex */
    uint32_t nv, vcap;
    uint32_t *faces;
    uint32_t nf, fcap;
    int oom;
} geo_t;

static void geo_free(geo_t *g)
{
    free(g->pos), free(g->jnt), free(g->wgt), free(g->faces);
    memset(g, 0, sizeof *g);
}

static uint32_t geo_vertex(geo_t *g, v3 p, const uint16_t *j4, const float *w4)
{
    if (g->nv == g->vcap) {
        uint32_t cap = g->vcap ? 2 * g->vcap : 256;
        float *np = realloc(g->pos, 3 * (size_t)cap * sizeof *np);
        if (np) g->pos = np;
        uint16_t *nj = realloc(g->jnt, 4 * (size_t)cap * sizeof *nj);
        if (nj) g->jnt = nj;
        float *nw = realloc(g->wgt, 4 * (size_t)cap * sizeof *nw);
        if (nw) g->wgt = nw;
        if (!np || !nj || !nw) {
            g->oom = 1;
            return 0;
        }
        g->vcap = cap;
    }
    vstore(g->pos + 3 * (size_t)g->nv, p);
    memcpy(g->jnt + 4 * (size_t)g->nv, j4, 4 * sizeof *j4);
    memcpy(g->wgt + 4 * (size_t)g->nv, w4, 4 * sizeof *w4);
    return g->nv++;
}

/* A vertex skinned rigidly to joint j. */
static uint32_t geo_rigid(geo_t *g, v3 p, int j)
{
    const uint16_t j4[4] = {(uint16_t)j, 0, 0, 0};
    const float w4[4] = {1, 0, 0, 0};
    return geo_vertex(g, p, j4, w4);
}

static void geo_face(geo_t *g, uint32_t a, uint32_t b, uint32_t c)
{
    if (g->nf == g->fcap) {
        uint32_t cap = g->fcap ? 2 * g->fcap : 256;
        uint32_t *nf = realloc(g->faces, 3 * (size_t)cap * sizeof *nf);
        if (!nf) {
            g->oom = 1;
            return;
        }
        g->faces = nf, g->fcap = cap;
    }
    uint32_t *f = g->faces + 3 * (size_t)g->nf++;
    f[0] = a, f[1] = b, f[2] = c;
}

/* A lat-long sphere (poles on Y), counter-clockwise seen from outside. */
static void geo_sphere(geo_t *g, v3 c, double r, int rings, int segs, int joint)
{
    uint32_t top = geo_rigid(g, vadd(c, V(0, r, 0)), joint), first = g->nv;
    for (int i = 1; i < rings; i++) {
        double ph = M_PI * i / rings;
        for (int k = 0; k < segs; k++) {
            double th = 2 * M_PI * k / segs;
            geo_rigid(g, vadd(c, V(r * sin(ph) * sin(th), r * cos(ph), r * sin(ph) * cos(th))), joint);
        }
    }
    uint32_t bottom = geo_rigid(g, vadd(c, V(0, -r, 0)), joint);
#define RING(i, k) (first + (uint32_t)((i)-1) * (uint32_t)segs + (uint32_t)((k) % segs))
    for (int k = 0; k < segs; k++) {
        geo_face(g, top, RING(1, k), RING(1, k + 1));
        for (int i = 1; i < rings - 1; i++) {
            geo_face(g, RING(i, k), RING(i + 1, k), RING(i + 1, k + 1));
            geo_face(g, RING(i, k), RING(i + 1, k + 1), RING(i, k + 1));
        }
        geo_face(g, RING(rings - 1, k), bottom, RING(rings - 1, k + 1));
    }
#undef RING
}

/* A torus around axis a through c (major radius R, tube radius r). */
static void geo_torus(geo_t *g, v3 c, v3 a, double R, double r, int nu, int nv, int joint)
{
    a = vnorm(a);
    v3 e1 = vnorm(fabs(a.y) < 0.9 ? vcross(V(0, 1, 0), a) : vcross(V(1, 0, 0), a)), e2 = vcross(a, e1);
    uint32_t first = g->nv;
    for (int i = 0; i < nu; i++) {
        double u = 2 * M_PI * i / nu;
        v3 rho = vadd(vscale(e1, cos(u)), vscale(e2, sin(u)));
        for (int j = 0; j < nv; j++) {
            double v = 2 * M_PI * j / nv;
            geo_rigid(g, vadd(c, vadd(vscale(rho, R + r * cos(v)), vscale(a, r * sin(v)))), joint);
        }
    }
#define T(i, j) (first + (uint32_t)((i) % nu) * (uint32_t)nv + (uint32_t)((j) % nv))
    for (int i = 0; i < nu; i++)
        for (int j = 0; j < nv; j++) {
            geo_face(g, T(i, j), T(i + 1, j), T(i + 1, j + 1));
            geo_face(g, T(i, j), T(i + 1, j + 1), T(i, j + 1));
        }
#undef T
}

/* A box [lo, hi] (no rotation), faces oriented outwards. */
static void geo_box(geo_t *g, v3 lo, v3 hi, int joint)
{
    uint32_t first = g->nv;
    for (int i = 0; i < 8; i++) geo_rigid(g, V(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z), joint);
    /* each side: the four corners in cyclic order; flipped when inwards */
    static const int quad[6][4] = {{0, 2, 6, 4}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 5, 7, 6}};
    v3 mid = vscale(vadd(lo, hi), 0.5);
    for (int s = 0; s < 6; s++) {
        uint32_t q[4];
        for (int k = 0; k < 4; k++) q[k] = first + (uint32_t)quad[s][k];
        v3 p0 = vload(g->pos + 3 * q[0]), p1 = vload(g->pos + 3 * q[1]), p2 = vload(g->pos + 3 * q[2]);
        if (vdot(vcross(vsub(p1, p0), vsub(p2, p0)), vsub(p0, mid)) < 0) {
            uint32_t t = q[1];
            q[1] = q[3], q[3] = t;
        }
        geo_face(g, q[0], q[1], q[2]);
        geo_face(g, q[0], q[2], q[3]);
    }
}

/* Area-weighted vertex normals (3 * nv, malloc'd). */
static float *vertex_normals(const float *pos, uint32_t nv, const uint32_t *faces, uint32_t nf)
{
    double *acc = calloc(3 * (size_t)nv + 1, sizeof *acc);
    float *n = malloc((3 * (size_t)nv + 1) * sizeof *n);
    if (!acc || !n) {
        free(acc), free(n);
        return NULL;
    }
    for (uint32_t f = 0; f < nf; f++) {
        const uint32_t *t = faces + 3 * (size_t)f;
        v3 a = vload(pos + 3 * (size_t)t[0]), b = vload(pos + 3 * (size_t)t[1]), c = vload(pos + 3 * (size_t)t[2]);
        v3 fn = vcross(vsub(b, a), vsub(c, a)); /* twice the area times the normal */
        for (int k = 0; k < 3; k++) {
            double *d = acc + 3 * (size_t)t[k];
            d[0] += fn.x, d[1] += fn.y, d[2] += fn.z;
        }
    }
    for (uint32_t v = 0; v < nv; v++)
        vstore(n + 3 * (size_t)v, vnorm(V(acc[3 * (size_t)v], acc[3 * (size_t)v + 1], acc[3 * (size_t)v + 2])));
    free(acc);
    return n;
}

/* ---- primitives as written ---- */
typedef struct prim {
    char mesh[64];
    int is_body, material; /* material -1: none */
    int skinned;           /* JOINTS_0 and WEIGHTS_0 written */
    uint32_t nv, nf;
    float *pos;    /* 3 nv, metres: world (final frame), or its node's frame for the sword */
    float *nrm;    /* 3 nv */
    float *uv;     /* 2 nv */
    uint16_t *jnt; /* 4 nv */
    float *wgt;    /* 4 nv */
    uint32_t *idx; /* 3 nf */
} prim_t;

static void prim_free(prim_t *p)
{
    free(p->pos), free(p->nrm), free(p->uv), free(p->jnt), free(p->wgt), free(p->idx);
    memset(p, 0, sizeof *p);
}

typedef struct corner {
    uint32_t v, key, c;
} corner_t;

static int corner_cmp(const void *pa, const void *pb)
{
    const corner_t *a = pa, *b = pb;
    if (a->v != b->v) return a->v < b->v ? -1 : 1;
    if (a->key != b->key) return a->key < b->key ? -1 : 1;
    return a->c < b->c ? -1 : a->c > b->c;
}

/* A primitive of the faces `faces` (nf triangles of g's vertices) with
 * per-corner UVs (2 * 3 nf) and keys (3 nf; NULL: all 0). Corners with the
 * same vertex and key share one vertex (numbered by g's vertex, then key),
 * copies of a vertex have bitwise equal positions; flat: every corner its
 * own vertex with the face normal. nrm: g's vertex normals. */
static int build_prim(prim_t *pr, const geo_t *g, const float *nrm, const uint32_t *faces, uint32_t nf,
                      const float *cuv, const uint32_t *ckey, int flat)
{
    const size_t nc = 3 * (size_t)nf;
    pr->nf = nf;
    pr->idx = malloc((nc + 1) * sizeof *pr->idx);
    corner_t *cs = flat ? NULL : malloc((nc + 1) * sizeof *cs);
    if (!pr->idx || (!flat && !cs)) {
        free(cs);
        return MIM_ENOMEM;
    }
    uint32_t nv = (uint32_t)nc;
    if (!flat) {
        for (size_t c = 0; c < nc; c++) cs[c] = (corner_t){faces[c], ckey ? ckey[c] : 0, (uint32_t)c};
        qsort(cs, nc, sizeof *cs, corner_cmp);
        nv = 0;
        for (size_t i = 0; i < nc; i++) {
            if (i && (cs[i].v != cs[i - 1].v || cs[i].key != cs[i - 1].key)) nv++;
            pr->idx[cs[i].c] = nv;
        }
        nv += nc > 0;
    }
    pr->nv = nv;
    pr->pos = malloc((3 * (size_t)nv + 1) * sizeof(float));
    pr->nrm = malloc((3 * (size_t)nv + 1) * sizeof(float));
    pr->uv = malloc((2 * (size_t)nv + 1) * sizeof(float));
    pr->jnt = malloc((4 * (size_t)nv + 1) * sizeof(uint16_t));
    pr->wgt = malloc((4 * (size_t)nv + 1) * sizeof(float));
    if (!pr->pos || !pr->nrm || !pr->uv || !pr->jnt || !pr->wgt) {
        free(cs);
        return MIM_ENOMEM;
    }
    for (size_t c = 0; c < nc; c++) {
        uint32_t v = faces[c], out;
        if (flat) {
            out = (uint32_t)c;
            pr->idx[c] = out;
            const uint32_t *t = faces + 3 * (c / 3);
            v3 a = vload(g->pos + 3 * (size_t)t[0]), b = vload(g->pos + 3 * (size_t)t[1]),
               d = vload(g->pos + 3 * (size_t)t[2]);
            vstore(pr->nrm + 3 * (size_t)out, vnorm(vcross(vsub(b, a), vsub(d, a))));
        } else {
            out = pr->idx[c];
            memcpy(pr->nrm + 3 * (size_t)out, nrm + 3 * (size_t)v, 3 * sizeof(float));
        }
        memcpy(pr->pos + 3 * (size_t)out, g->pos + 3 * (size_t)v, 3 * sizeof(float));
        memcpy(pr->uv + 2 * (size_t)out, cuv + 2 * c, 2 * sizeof(float));
        memcpy(pr->jnt + 4 * (size_t)out, g->jnt + 4 * (size_t)v, 4 * sizeof(uint16_t));
        memcpy(pr->wgt + 4 * (size_t)out, g->wgt + 4 * (size_t)v, 4 * sizeof(float));
    }
    free(cs);
    return 0;
}

/* Per-corner UVs of a shell: a cylinder about the vertical through its centre. */
static float *shell_uv(const geo_t *g)
{
    float *cuv = malloc((6 * (size_t)g->nf + 1) * sizeof *cuv);
    if (!cuv) return NULL;
    v3 c = V(0, 0, 0);
    for (uint32_t v = 0; v < g->nv; v++) c = vadd(c, vload(g->pos + 3 * (size_t)v));
    c = vscale(c, 1.0 / (g->nv ? g->nv : 1));
    for (size_t k = 0; k < 3 * (size_t)g->nf; k++) {
        v3 d = vsub(vload(g->pos + 3 * (size_t)g->faces[k]), c);
        double u = 0.5 + atan2(d.x, d.z) / (2 * M_PI), v = 0.5 - d.y / 2;
        cuv[2 * k] = (float)fmin(1, fmax(0, u));
        cuv[2 * k + 1] = (float)fmin(1, fmax(0, v));
    }
    return cuv;
}

/* ---- the avatar under construction ---- */
typedef struct mesh_def {
    const char *name;
    uint32_t first, count; /* its primitives */
} mesh_def_t;

typedef struct build {
    const ra_options_t *o;
    int skinned, vrm0;
    double unit; /* 100 in centimetres, else 1 */
    uint32_t nb, fb;
    const uint32_t *faces;    /* the synth's */
    geo_t body;               /* the synth body: positions (fists applied), its skin */
    float *bn;                /* body vertex normals */
    uint8_t *vbone;           /* nearest bone of each body vertex */
    v3 J[NJ], sa[NJ], sb[NJ]; /* joints, bone segments (synth frame) */
    int parent[NJ];
    double H; /* stature */
    prim_t prim[RA_MAX_PRIMITIVES];
    uint32_t np;
    mesh_def_t mesh[8];
    uint32_t nm;
    int sword_mesh;               /* its index in mesh[], -1: none */
    float sword_t[3], sword_q[4]; /* the sword node (file units, final frame) */
} build_t;

static prim_t *new_prim(build_t *b, const char *mesh, int is_body)
{
    if (b->np == RA_MAX_PRIMITIVES) return NULL;
    prim_t *p = &b->prim[b->np++];
    memset(p, 0, sizeof *p);
    snprintf(p->mesh, sizeof p->mesh, "%s", mesh);
    p->is_body = is_body;
    p->material = b->o->texture ? 0 : -1;
    p->skinned = b->skinned;
    b->mesh[b->nm - 1].count++;
    return p;
}

static void begin_mesh(build_t *b, const char *name) { b->mesh[b->nm++] = (mesh_def_t){name, b->np, 0}; }

static double seg_dist(v3 p, v3 a, v3 b)
{
    v3 ab = vsub(b, a);
    double l2 = vdot(ab, ab), t = l2 > 0 ? vdot(vsub(p, a), ab) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return vlen(vsub(p, vadd(a, vscale(ab, t))));
}

static int nearest_bone(const build_t *b, v3 p, int *second, double *d0, double *d1)
{
    int i0 = 0, i1 = 1;
    double e0 = 1e300, e1 = 1e300;
    for (int j = 0; j < NJ; j++) {
        double d = seg_dist(p, b->sa[j], b->sb[j]);
        if (d < e0)
            e1 = e0, i1 = i0, e0 = d, i0 = j;
        else if (d < e1)
            e1 = d, i1 = j;
    }
    if (second) *second = i1;
    if (d0) *d0 = e0;
    if (d1) *d1 = e1;
    return i0;
}

/* Bones: joint to child joint; end bones (head, hands, feet) a short
 * segment onwards (along the parent bone; the foot's towards the toes). */
static void make_bones(build_t *b)
{
    for (int j = 0; j < NJ; j++) {
        b->sa[j] = b->J[j];
        if (bone_child[j] >= 0) {
            b->sb[j] = b->J[bone_child[j]];
        } else if (j == J_HEAD) {
            double len = fmax(0.05, 0.7 * (b->H - b->J[J_HEAD].y));
            b->sb[j] = vadd(b->J[j], vscale(vnorm(vsub(b->J[J_HEAD], b->J[J_NECK])), len));
        } else if (j == J_LHAND || j == J_RHAND) {
            v3 fa = vsub(b->J[j], b->J[j == J_LHAND ? J_LFARM : J_RFARM]);
            b->sb[j] = vadd(b->J[j], vscale(vnorm(fa), 0.45 * vlen(fa)));
        } else { /* feet */
            b->sb[j] = vadd(b->J[j], vscale(vnorm(V(0, -0.27, 1)), 0.1 * b->H));
        }
    }
}

/* Each body vertex on its two nearest bones, weights by inverse distance;
 * then the fists (the hand's vertices past the wrist pulled towards a
 * point 4 cm beyond it, smoothly over the first 3 cm) and the normals. */
static int make_body_skin(build_t *b)
{
    geo_t *g = &b->body;
    b->vbone = malloc(b->nb + 1);
    if (!b->vbone) return MIM_ENOMEM;
    for (uint32_t v = 0; v < b->nb; v++) {
        int i1;
        double d0, d1;
        int i0 = nearest_bone(b, vload(g->pos + 3 * (size_t)v), &i1, &d0, &d1);
        double w0 = 1 / (d0 + 1e-3), w1 = 1 / (d1 + 1e-3);
        float f0 = (float)(w0 / (w0 + w1));
        uint16_t *j4 = g->jnt + 4 * (size_t)v;
        float *w4 = g->wgt + 4 * (size_t)v;
        j4[0] = (uint16_t)i0, j4[1] = (uint16_t)i1, j4[2] = j4[3] = 0;
        w4[0] = f0, w4[1] = 1.0f - f0, w4[2] = w4[3] = 0;
        b->vbone[v] = (uint8_t)i0;
    }
    if (b->o->fists) {
        for (uint32_t v = 0; v < b->nb; v++) {
            int h = b->vbone[v];
            if (h != J_LHAND && h != J_RHAND) continue;
            v3 w = b->J[h], d = vnorm(vsub(w, b->J[h == J_LHAND ? J_LFARM : J_RFARM]));
            v3 p = vload(g->pos + 3 * (size_t)v);
            double t = vdot(vsub(p, w), d);
            if (t <= 0) continue;
            double s = 1 - 0.55 * fmin(1, t / 0.03);
            v3 c = vadd(w, vscale(d, 0.04));
            vstore(g->pos + 3 * (size_t)v, vadd(c, vscale(vsub(p, c), s)));
        }
    }
    b->bn = vertex_normals(g->pos, b->nb, b->faces, b->fb);
    return b->bn ? 0 : MIM_ENOMEM;
}

/* A cylindrical UV chart: angle about axis a (0 at the front r, the cut
 * at the back), length along it; placed in the tile (u0, v0, du, dv). */
typedef struct chart {
    v3 o, a, r, s;
    double len, u0, v0, du, dv;
    int trunk;
} chart_t;

static chart_t make_chart(v3 o, v3 a, double len, double u0, double v0, double du, double dv, int trunk)
{
    chart_t c = {.o = o, .a = vnorm(a), .len = len, .u0 = u0, .v0 = v0, .du = du, .dv = dv, .trunk = trunk};
    c.r = vnorm(vsub(V(0, 0, 1), vscale(c.a, c.a.z)));
    c.s = vcross(c.a, c.r);
    return c;
}

static double chart_angle(const chart_t *c, v3 p)
{
    v3 q = vsub(p, c->o);
    return atan2(vdot(q, c->s), vdot(q, c->r));
}

static double chart_v(const chart_t *c, v3 p)
{
    double t = c->trunk ? 1 - p.y / c->len : vdot(vsub(p, c->o), c->a) / c->len;
    return fmin(1, fmax(0, t));
}

/* The body: its UVs per corner (with split_seams an island per body part,
 * each cut at its back, the faces across a cut using copies of the
 * vertices on one side) and its one or two primitives. */
static int make_body(build_t *b)
{
    const ra_options_t *o = b->o;
    const int seams = o->split_seams;
    const size_t nc = 3 * (size_t)b->fb;
    chart_t ch[5];
    ch[0] = make_chart(V(0, 0, 0), V(0, 1, 0), b->H, 0, 0, seams ? 0.5 : 1, 1, 1);
    for (int side = 0; side < 2; side++) {
        int ua = side ? J_RUARM : J_LUARM, hand = side ? J_RHAND : J_LHAND;
        int th = side ? J_RTHIGH : J_LTHIGH, ft = side ? J_RFOOT : J_LFOOT;
        v3 arm = vsub(b->sb[hand], b->J[ua]), leg = vsub(b->J[ft], b->J[th]);
        ch[1 + side] = make_chart(b->J[ua], arm, vlen(arm), 0.5 + 0.25 * side, 0, 0.25, 0.5, 0);
        ch[3 + side] = make_chart(b->J[th], leg, vlen(leg) + b->J[ft].y, 0.5 + 0.25 * side, 0.5, 0.25, 0.5, 0);
    }
    double *ang = malloc((nc + 1) * sizeof *ang);
    uint32_t *key = malloc((nc + 1) * sizeof *key);
    float *cuv = malloc((2 * nc + 1) * sizeof *cuv);
    uint8_t *region = malloc(b->fb + 1), *lower = malloc(b->fb + 1);
    int rc = MIM_ENOMEM;
    if (!ang || !key || !cuv || !region || !lower) goto done;
    double over = 0; /* how far the copies' angles reach past +-pi */
    for (uint32_t f = 0; f < b->fb; f++) {
        const uint32_t *t = b->faces + 3 * (size_t)f;
        v3 p[3], cen = V(0, 0, 0);
        for (int k = 0; k < 3; k++) p[k] = vload(b->body.pos + 3 * (size_t)t[k]), cen = vadd(cen, p[k]);
        int bone = nearest_bone(b, vscale(cen, 1.0 / 3), NULL, NULL, NULL);
        region[f] = (uint8_t)(seams ? bone_region[bone] : 0);
        lower[f] = bone == J_PELVIS || bone_region[bone] >= 3;
        double *a = ang + 3 * (size_t)f;
        int npos = 0;
        for (int k = 0; k < 3; k++) {
            a[k] = chart_angle(&ch[region[f]], p[k]);
            npos += a[k] > 0;
            key[3 * (size_t)f + k] = 2u * region[f];
        }
        double lo = fmin(a[0], fmin(a[1], a[2])), hi = fmax(a[0], fmax(a[1], a[2]));
        if (!seams || hi - lo <= M_PI) continue;
        /* across the cut: the corners on the minority side use copies whose
         * angle continues past +-pi (a copy's angle depends on its vertex
         * alone); not around the chart's axis (a pole), where no shift
         * makes the face narrow */
        double s[3];
        for (int k = 0; k < 3; k++)
            s[k] = (npos >= 2 ? a[k] <= 0 : a[k] > 0) ? a[k] + (a[k] <= 0 ? 2 : -2) * M_PI : a[k];
        if (fmax(s[0], fmax(s[1], s[2])) - fmin(s[0], fmin(s[1], s[2])) > M_PI / 2) continue;
        for (int k = 0; k < 3; k++) {
            if (s[k] == a[k]) continue;
            a[k] = s[k];
            key[3 * (size_t)f + k] |= 1;
            over = fmax(over, fabs(a[k]) - M_PI);
        }
    }
    for (size_t c = 0; c < nc; c++) {
        const chart_t *h = &ch[region[c / 3]];
        double u = (ang[c] + M_PI + over) / (2 * M_PI + 2 * over);
        double v = chart_v(h, vload(b->body.pos + 3 * (size_t)b->faces[c]));
        cuv[2 * c] = (float)(h->u0 + h->du * fmin(1, fmax(0, u)));
        cuv[2 * c + 1] = (float)(h->v0 + h->dv * v);
    }
    /* the primitives: all faces, or the upper body then the lower */
    const int parts = o->two_primitives ? 2 : 1;
    uint32_t *pf = malloc((nc + 1) * sizeof *pf), *pk = malloc((nc + 1) * sizeof *pk);
    float *pu = malloc((2 * nc + 1) * sizeof *pu);
    if (!pf || !pk || !pu) {
        free(pf), free(pk), free(pu);
        goto done;
    }
    begin_mesh(b, "Body");
    rc = 0;
    for (int part = 0; part < parts && !rc; part++) {
        uint32_t n = 0;
        for (uint32_t f = 0; f < b->fb; f++) {
            if (parts == 2 && lower[f] != part) continue;
            memcpy(pf + 3 * (size_t)n, b->faces + 3 * (size_t)f, 3 * sizeof *pf);
            memcpy(pk + 3 * (size_t)n, key + 3 * (size_t)f, 3 * sizeof *pk);
            memcpy(pu + 6 * (size_t)n, cuv + 6 * (size_t)f, 6 * sizeof *pu);
            n++;
        }
        prim_t *pr = new_prim(b, "Body", 1);
        if (!pr) {
            rc = MIM_EINVAL;
            break;
        }
        if (part == 1 && o->texture) pr->material = 1; /* the lower body's "Cloth" */
        rc = build_prim(pr, &b->body, b->bn, pf, n, pu, pk, o->flat);
    }
    free(pf), free(pk), free(pu);
done:
    free(ang), free(key), free(cuv), free(region), free(lower);
    return rc;
}

/* One shell primitive (its own mesh) from g. */
static int add_shell(build_t *b, const char *name, geo_t *g)
{
    if (g->oom) return MIM_ENOMEM;
    begin_mesh(b, name);
    prim_t *pr = new_prim(b, name, 0);
    float *n = vertex_normals(g->pos, g->nv, g->faces, g->nf), *cuv = shell_uv(g);
    int rc = !pr ? MIM_EINVAL : n && cuv ? build_prim(pr, g, n, g->faces, g->nf, cuv, NULL, b->o->flat) : MIM_ENOMEM;
    free(n), free(cuv);
    return rc;
}

static int make_rings(build_t *b)
{
    geo_t g = {0};
    for (int j = 0; j < NJ; j++) geo_torus(&g, b->J[j], vsub(b->sb[j], b->sa[j]), 0.03, 0.005, 12, 6, j);
    int rc = add_shell(b, "JointRings", &g);
    geo_free(&g);
    return rc;
}

/* Two eyeballs sunk half into the face at eye height. */
static int make_eyes(build_t *b)
{
    const double k = b->H / 1.75, r = 0.012 * k, yn = b->J[J_NECK].y;
    const double y = yn + (0.946 - 0.834) / (1 - 0.834) * (b->H - yn);
    geo_t g = {0};
    for (int side = 0; side < 2; side++) {
        double x = (side ? -0.032 : 0.032) * k, zmax = -1e300;
        for (double tol = 0.01; zmax == -1e300 && tol < 0.2; tol *= 2)
            for (uint32_t v = 0; v < b->nb; v++) {
                const float *p = b->body.pos + 3 * (size_t)v;
                if ((b->vbone[v] == J_HEAD || b->vbone[v] == J_NECK) && fabs(p[1] - y) < tol && fabs(p[0] - x) < tol)
                    zmax = fmax(zmax, p[2]);
            }
        if (zmax == -1e300) zmax = b->J[J_HEAD].z + 0.05 * k;
        geo_sphere(&g, V(x, y, zmax - 0.5 * r), r, 8, 12, J_HEAD);
    }
    int rc = add_shell(b, "Eyes", &g);
    geo_free(&g);
    return rc;
}

static int edge_cmp(const void *pa, const void *pb)
{
    uint64_t a = *(const uint64_t *)pa, b = *(const uint64_t *)pb;
    return a < b ? -1 : a > b;
}

/* Boots: the body's faces below the ankle joint pushed 5 mm out along the
 * vertex normals, closed by a fan over the cut at the ankle (every cut
 * edge a -> b gets the triangle b, a, centre); each vertex keeps the skin
 * of the body vertex it comes from, the centre hangs on the foot. */
static int make_boots(build_t *b)
{
    geo_t g = {0};
    uint32_t *map = malloc((b->nb + 1) * sizeof *map);
    uint64_t *edges = malloc((3 * (size_t)b->fb + 1) * sizeof *edges);
    uint32_t *sel = malloc((b->fb + 1) * sizeof *sel);
    int rc = MIM_ENOMEM;
    if (!map || !edges || !sel) goto done;
    for (int side = 0; side < 2; side++) {
        const int foot = side ? J_RFOOT : J_LFOOT;
        const double sx = side ? -1 : 1, ytop = b->J[foot].y + 0.01;
        uint32_t ns = 0, ne = 0;
        for (uint32_t v = 0; v < b->nb; v++) map[v] = UINT32_MAX;
        for (uint32_t f = 0; f < b->fb; f++) {
            const uint32_t *t = b->faces + 3 * (size_t)f;
            int in = 1;
            for (int k = 0; k < 3; k++) {
                const float *p = b->body.pos + 3 * (size_t)t[k];
                in &= p[0] * sx > 0 && p[1] < ytop;
            }
            if (!in) continue;
            sel[ns++] = f;
            for (int k = 0; k < 3; k++) edges[ne++] = (uint64_t)t[k] << 32 | t[(k + 1) % 3];
        }
        if (ns == 0) {
            rc = MIM_EINVAL;
            goto done;
        }
        qsort(edges, ne, sizeof *edges, edge_cmp);
        for (uint32_t i = 0; i < ns; i++) {
            const uint32_t *t = b->faces + 3 * (size_t)sel[i];
            uint32_t w[3];
            for (int k = 0; k < 3; k++) {
                uint32_t v = t[k];
                if (map[v] == UINT32_MAX) {
                    v3 p = vadd(vload(b->body.pos + 3 * (size_t)v), vscale(vload(b->bn + 3 * (size_t)v), 0.005));
                    map[v] = geo_vertex(&g, p, b->body.jnt + 4 * (size_t)v, b->body.wgt + 4 * (size_t)v);
                }
                w[k] = map[v];
            }
            geo_face(&g, w[0], w[1], w[2]);
        }
        if (g.oom) break;
        /* the cut: directed edges whose reverse is not among the faces */
        v3 cen = V(0, 0, 0);
        uint32_t ncut = 0;
        for (uint32_t i = 0; i < ne; i++) {
            uint64_t rev = edges[i] << 32 | edges[i] >> 32;
            if (bsearch(&rev, edges, ne, sizeof *edges, edge_cmp)) continue;
            cen = vadd(cen, vload(g.pos + 3 * (size_t)map[edges[i] >> 32]));
            ncut++;
        }
        if (ncut == 0) continue; /* cannot happen on a closed body */
        uint32_t c = geo_rigid(&g, vscale(cen, 1.0 / ncut), foot);
        for (uint32_t i = 0; i < ne; i++) {
            uint64_t rev = edges[i] << 32 | edges[i] >> 32;
            if (!bsearch(&rev, edges, ne, sizeof *edges, edge_cmp))
                geo_face(&g, map[(uint32_t)edges[i]], map[edges[i] >> 32], c);
        }
    }
    rc = add_shell(b, "Boots", &g);
done:
    free(map), free(edges), free(sel);
    geo_free(&g);
    return rc;
}

/* A sword in the right hand: a box along its node's +Y (grip at the
 * origin, 0.15 m of hilt behind, 0.65 m of blade ahead), the node turned so
 * that the blade points forwards and down, its edge tilted by 20 degrees. */
static int make_sword(build_t *b)
{
    v3 w = b->J[J_RHAND], d = vnorm(vsub(w, b->J[J_RFARM]));
    v3 t = vscale(d, 0.04); /* the grip, in the middle of the (closed) hand */
    v3 ey = vnorm(V(0, -0.35, 1)), ex = V(1, 0, 0), ez = vcross(ex, ey);
    const double tw = 20 * M_PI / 180;
    v3 ex2 = vadd(vscale(ex, cos(tw)), vscale(ez, sin(tw))), ez2 = vcross(ex2, ey);
    if (b->vrm0) {
        t = V(-t.x, t.y, -t.z), ex2 = V(-ex2.x, ex2.y, -ex2.z);
        ey = V(-ey.x, ey.y, -ey.z), ez2 = V(-ez2.x, ez2.y, -ez2.z);
    }
    double q[4];
    quat_of_axes(ex2, ey, ez2, q);
    vstore(b->sword_t, vscale(t, b->unit));
    for (int i = 0; i < 4; i++) b->sword_q[i] = (float)q[i];
    geo_t g = {0};
    geo_box(&g, V(-0.015, -0.15, -0.005), V(0.015, 0.65, 0.005), J_RHAND);
    b->sword_mesh = (int)b->nm;
    int rc = add_shell(b, "Sword", &g);
    if (!rc) b->prim[b->np - 1].skinned = 0; /* it hangs on its node */
    geo_free(&g);
    return rc;
}

/* ---- the PNG texture: a 16x16 checker, stored (uncompressed) deflate ---- */
static uint32_t crc32_of(const unsigned char *p, size_t n, uint32_t crc)
{
    crc = ~crc;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++) crc = crc & 1 ? (crc >> 1) ^ 0xEDB88320u : crc >> 1;
    }
    return ~crc;
}

static unsigned char *put32be(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)(v >> 24), p[1] = (unsigned char)(v >> 16), p[2] = (unsigned char)(v >> 8);
    p[3] = (unsigned char)v;
    return p + 4;
}

/* A PNG chunk at p: length, type, data, CRC of type and data. */
static unsigned char *png_chunk(unsigned char *p, const char *type, const unsigned char *data, uint32_t n)
{
    p = put32be(p, n);
    unsigned char *start = p;
    memcpy(p, type, 4);
    if (n) memcpy(p + 4, data, n);
    p += 4 + n;
    return put32be(p, crc32_of(start, 4 + (size_t)n, 0));
}

#define PNG_SIDE 16
#define PNG_RAW (PNG_SIDE * (1 + 3 * PNG_SIDE))
#define PNG_MAX (8 + 25 + 12 + 2 + 5 + PNG_RAW + 4 + 12 + 16)

static size_t make_png(unsigned char out[PNG_MAX])
{
    unsigned char raw[PNG_RAW], *r = raw;
    for (int y = 0; y < PNG_SIDE; y++) {
        *r++ = 0; /* filter: none */
        for (int x = 0; x < PNG_SIDE; x++) {
            int dark = ((x / 4) + (y / 4)) & 1;
            *r++ = dark ? 150 : 224, *r++ = dark ? 105 : 172, *r++ = dark ? 80 : 140;
        }
    }
    unsigned char ihdr[13], *h = put32be(ihdr, PNG_SIDE);
    h = put32be(h, PNG_SIDE);
    h[0] = 8, h[1] = 2, h[2] = 0, h[3] = 0, h[4] = 0; /* 8 bit RGB, no interlace */
    /* zlib: header, one final stored block, Adler-32 */
    unsigned char z[2 + 5 + PNG_RAW + 4], *zp = z;
    *zp++ = 0x78, *zp++ = 0x01;
    *zp++ = 1, *zp++ = PNG_RAW & 0xff, *zp++ = PNG_RAW >> 8;
    *zp++ = (unsigned char)(~PNG_RAW & 0xff), *zp++ = (unsigned char)((~PNG_RAW >> 8) & 0xff);
    memcpy(zp, raw, PNG_RAW);
    zp += PNG_RAW;
    uint32_t a = 1, bsum = 0;
    for (size_t i = 0; i < PNG_RAW; i++) a = (a + raw[i]) % 65521, bsum = (bsum + a) % 65521;
    zp = put32be(zp, bsum << 16 | a);
    unsigned char *p = out;
    memcpy(p, "\x89PNG\r\n\x1a\n", 8);
    p = png_chunk(p + 8, "IHDR", ihdr, 13);
    p = png_chunk(p, "IDAT", z, (uint32_t)(zp - z));
    p = png_chunk(p, "IEND", NULL, 0);
    return (size_t)(p - out);
}

/* ---- the GLB ---- */
typedef struct out {
    unsigned char *bin;
    size_t len, cap;
    char *views, *accs;
    size_t views_len, accs_len;
    FILE *vf, *af;
    uint32_t n_views, n_accs;
    int oom;
} out_t;

/* A bufferView of a copy of data (4-byte aligned); its index. */
static uint32_t out_view(out_t *o, const void *data, size_t n, int target)
{
    size_t off = (o->len + 3) & ~(size_t)3;
    if (off + n > o->cap) {
        size_t cap = o->cap ? o->cap : 65536;
        while (cap < off + n) cap *= 2;
        unsigned char *nb = realloc(o->bin, cap);
        if (!nb) {
            o->oom = 1;
            return 0;
        }
        o->bin = nb, o->cap = cap;
    }
    memset(o->bin + o->len, 0, off - o->len);
    if (n) memcpy(o->bin + off, data, n);
    o->len = off + n;
    fprintf(o->vf, "%s{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu", o->n_views ? "," : "", off, n);
    if (target) fprintf(o->vf, ",\"target\":%d", target);
    fputc('}', o->vf);
    return o->n_views++;
}

/* An accessor over its own bufferView; mn/mx (ncomp floats) or NULL. */
static uint32_t out_accessor(out_t *o, const void *data, size_t n, int target, int ctype, uint32_t count,
                             const char *type, const float *mn, const float *mx, int ncomp)
{
    uint32_t view = out_view(o, data, n, target);
    fprintf(o->af, "%s{\"bufferView\":%u,\"componentType\":%d,\"count\":%u,\"type\":\"%s\"", o->n_accs ? "," : "", view,
            ctype, count, type);
    if (mn && mx) {
        for (int m = 0; m < 2; m++) {
            const float *v = m ? mx : mn;
            fprintf(o->af, ",\"%s\":[", m ? "max" : "min");
            for (int i = 0; i < ncomp; i++) fprintf(o->af, "%s%.9g", i ? "," : "", (double)v[i]);
            fputc(']', o->af);
        }
    }
    fputc('}', o->af);
    return o->n_accs++;
}

static const char *joint_name(ra_names_t names, int j, char buf[16])
{
    if (names == RA_NAMES_MIXAMO) return mixamo_names[j];
    if (names == RA_NAMES_BLENDER) return blender_names[j];
    snprintf(buf, 16, "bone_%02d", j);
    return buf;
}

static int write_file(const char *path, const char *json, size_t jl, const unsigned char *bin, size_t bl)
{
    size_t jpad = (jl + 3) & ~(size_t)3, bpad = (bl + 3) & ~(size_t)3;
    if (12 + 8 + jpad + 8 + bpad > UINT32_MAX) return MIM_EINVAL;
    unsigned char head[12 + 8];
    memcpy(head, "glTF", 4);
    uint32_t u[4] = {2, (uint32_t)(12 + 8 + jpad + 8 + bpad), (uint32_t)jpad, 0x4E4F534Au}; /* "JSON" */
    memcpy(head + 4, u, 16); /* GLB is little-endian, as every platform mimic builds on */
    FILE *f = fopen(path, "wb");
    if (!f) return MIM_EIO;
    int ok = fwrite(head, 1, sizeof head, f) == sizeof head && fwrite(json, 1, jl, f) == jl;
    for (size_t i = jl; i < jpad; i++) ok &= fputc(' ', f) != EOF;
    uint32_t bh[2] = {(uint32_t)bpad, 0x004E4942u}; /* "BIN\0" */
    ok &= fwrite(bh, 1, 8, f) == 8 && (bl == 0 || fwrite(bin, 1, bl, f) == bl);
    for (size_t i = bl; i < bpad; i++) ok &= fputc(0, f) != EOF;
    ok &= fclose(f) == 0;
    return ok ? 0 : MIM_EIO;
}

/* The whole file: accessors per primitive, the rig, the JSON, the chunks. */
static int write_glb(const build_t *b, const char *path)
{
    const ra_options_t *o = b->o;
    const int with_uv = o->texture || o->split_seams;
    const double unit = b->unit;
    out_t ot = {0};
    char *json = NULL;
    size_t jl = 0;
    ot.vf = open_memstream(&ot.views, &ot.views_len);
    ot.af = open_memstream(&ot.accs, &ot.accs_len);
    FILE *js = open_memstream(&json, &jl);
    int rc = MIM_ENOMEM;
    uint32_t acc[RA_MAX_PRIMITIVES][6];
    if (!ot.vf || !ot.af || !js) goto done;

    /* the primitives' accessors: POSITION NORMAL TEXCOORD_0 JOINTS_0 WEIGHTS_0 indices */
    for (uint32_t i = 0; i < b->np; i++) {
        const prim_t *p = &b->prim[i];
        const size_t n3 = 3 * (size_t)p->nv;
        float *pos = malloc((n3 + 1) * sizeof *pos), mn[3] = {0, 0, 0}, mx[3] = {0, 0, 0};
        if (!pos) goto done;
        for (size_t k = 0; k < n3; k++) {
            pos[k] = (float)((double)p->pos[k] * unit);
            int a = (int)(k % 3);
            if (k < 3 || pos[k] < mn[a]) mn[a] = pos[k];
            if (k < 3 || pos[k] > mx[a]) mx[a] = pos[k];
        }
        acc[i][0] = out_accessor(&ot, pos, n3 * sizeof *pos, 34962, 5126, p->nv, "VEC3", mn, mx, 3);
        free(pos);
        acc[i][1] = out_accessor(&ot, p->nrm, n3 * sizeof(float), 34962, 5126, p->nv, "VEC3", NULL, NULL, 0);
        if (with_uv)
            acc[i][2] =
                out_accessor(&ot, p->uv, 2 * (size_t)p->nv * sizeof(float), 34962, 5126, p->nv, "VEC2", NULL, NULL, 0);
        if (p->skinned) {
            acc[i][3] = out_accessor(&ot, p->jnt, 4 * (size_t)p->nv * sizeof(uint16_t), 34962, 5123, p->nv, "VEC4",
                                     NULL, NULL, 0);
            acc[i][4] =
                out_accessor(&ot, p->wgt, 4 * (size_t)p->nv * sizeof(float), 34962, 5126, p->nv, "VEC4", NULL, NULL, 0);
        }
        const size_t ni = 3 * (size_t)p->nf;
        if (p->nv < 65536) {
            uint16_t *ix = malloc((ni + 1) * sizeof *ix);
            if (!ix) goto done;
            for (size_t k = 0; k < ni; k++) ix[k] = (uint16_t)p->idx[k];
            acc[i][5] = out_accessor(&ot, ix, ni * sizeof *ix, 34963, 5123, (uint32_t)ni, "SCALAR", NULL, NULL, 0);
            free(ix);
        } else {
            acc[i][5] =
                out_accessor(&ot, p->idx, ni * sizeof *p->idx, 34963, 5125, (uint32_t)ni, "SCALAR", NULL, NULL, 0);
        }
    }
    /* joints in the file's unit and frame */
    v3 Jf[NJ];
    for (int j = 0; j < NJ; j++) {
        v3 p = b->J[j];
        Jf[j] = vscale(b->vrm0 ? V(-p.x, p.y, -p.z) : p, unit);
    }
    uint32_t ibm_acc = 0, image_view = 0;
    if (b->skinned) {
        float ibm[16 * NJ];
        memset(ibm, 0, sizeof ibm);
        for (int j = 0; j < NJ; j++) {
            float *m = ibm + 16 * j;
            m[0] = m[5] = m[10] = m[15] = 1;
            m[12] = (float)-Jf[j].x, m[13] = (float)-Jf[j].y, m[14] = (float)-Jf[j].z;
        }
        ibm_acc = out_accessor(&ot, ibm, sizeof ibm, 0, 5126, NJ, "MAT4", NULL, NULL, 0);
    }
    if (o->texture) {
        unsigned char png[PNG_MAX];
        image_view = out_view(&ot, png, make_png(png), 0);
    }
    if (fclose(ot.vf) | fclose(ot.af)) {
        ot.vf = ot.af = NULL;
        goto done;
    }
    ot.vf = ot.af = NULL;
    if (ot.oom) goto done;

    /* nodes: the mesh nodes but the sword's (mesh order), Armature, the
     * joints (synth order), the sword */
    const uint32_t M = b->sword_mesh >= 0 ? b->nm - 1 : b->nm, arm = M, j0 = M + 1, sword = M + 1 + NJ;
    fprintf(js, "{\"asset\":{\"version\":\"2.0\",\"generator\":\"mimic tests rigged_avatar\"}");
    if (o->names == RA_NAMES_VRM0) {
        fprintf(js, ",\"extensionsUsed\":[\"VRM\"],\"extensions\":{\"VRM\":{\"specVersion\":\"0.0\","
                    "\"exporterVersion\":\"mimic tests\",\"meta\":{\"title\":\"mimic test avatar\",\"version\":\"1\","
                    "\"author\":\"mimic tests\"},\"humanoid\":{\"humanBones\":[");
        for (int j = 0; j < NJ; j++)
            fprintf(js, "%s{\"bone\":\"%s\",\"node\":%u,\"useDefaultValues\":true}", j ? "," : "", vrm_bones[j],
                    j0 + (uint32_t)j);
        fprintf(js, "]}}}");
    } else if (o->names == RA_NAMES_VRM1) {
        fprintf(js, ",\"extensionsUsed\":[\"VRMC_vrm\"],\"extensions\":{\"VRMC_vrm\":{\"specVersion\":\"1.0\","
                    "\"meta\":{\"name\":\"mimic test avatar\",\"version\":\"1\",\"authors\":[\"mimic tests\"],"
                    "\"licenseUrl\":\"https://vrm.dev/licenses/1.0/\"},\"humanoid\":{\"humanBones\":{");
        for (int j = 0; j < NJ; j++)
            fprintf(js, "%s\"%s\":{\"node\":%u}", j ? "," : "", vrm_bones[j], j0 + (uint32_t)j);
        fprintf(js, "}}}}");
    }
    fprintf(js, ",\"scene\":0,\"scenes\":[{\"name\":\"Scene\",\"nodes\":[");
    if (b->skinned)
        for (uint32_t m = 0; m < M; m++) fprintf(js, "%u,", m);
    fprintf(js, "%u]}],\"nodes\":[", arm);
    for (uint32_t m = 0; m < M; m++)
        fprintf(js, "{\"name\":\"%s\",\"mesh\":%u%s},", b->mesh[m].name, m, b->skinned ? ",\"skin\":0" : "");
    fprintf(js, "{\"name\":\"Armature\"%s,\"children\":[", o->centimetres ? ",\"scale\":[0.01,0.01,0.01]" : "");
    if (!b->skinned)
        for (uint32_t m = 0; m < M; m++) fprintf(js, "%u,", m);
    fprintf(js, "%u]}", j0);
    for (int j = 0; j < NJ; j++) {
        char buf[16];
        const int par = b->parent[j];
        v3 t = par < 0 ? Jf[j] : vsub(Jf[j], Jf[par]);
        fprintf(js, ",{\"name\":\"%s\",\"translation\":[%.9g,%.9g,%.9g]", joint_name(o->names, j, buf),
                (double)(float)t.x, (double)(float)t.y, (double)(float)t.z);
        int nc = 0;
        for (int c = 0; c < NJ; c++)
            if (b->parent[c] == j) fprintf(js, "%s%u", nc++ ? "," : ",\"children\":[", j0 + (uint32_t)c);
        if (j == J_RHAND && b->sword_mesh >= 0) fprintf(js, "%s%u", nc++ ? "," : ",\"children\":[", sword);
        fprintf(js, "%s}", nc ? "]" : "");
    }
    if (b->sword_mesh >= 0)
        fprintf(js,
                ",{\"name\":\"Sword\",\"mesh\":%d,\"translation\":[%.9g,%.9g,%.9g],\"rotation\":[%.9g,%.9g,%.9g,%.9g]}",
                b->sword_mesh, (double)b->sword_t[0], (double)b->sword_t[1], (double)b->sword_t[2],
                (double)b->sword_q[0], (double)b->sword_q[1], (double)b->sword_q[2], (double)b->sword_q[3]);
    fprintf(js, "],\"meshes\":[");
    for (uint32_t m = 0; m < b->nm; m++) {
        fprintf(js, "%s{\"name\":\"%s\",\"primitives\":[", m ? "," : "", b->mesh[m].name);
        for (uint32_t i = b->mesh[m].first; i < b->mesh[m].first + b->mesh[m].count; i++) {
            const prim_t *p = &b->prim[i];
            fprintf(js, "%s{\"attributes\":{\"POSITION\":%u,\"NORMAL\":%u", i > b->mesh[m].first ? "," : "", acc[i][0],
                    acc[i][1]);
            if (with_uv) fprintf(js, ",\"TEXCOORD_0\":%u", acc[i][2]);
            if (p->skinned) fprintf(js, ",\"JOINTS_0\":%u,\"WEIGHTS_0\":%u", acc[i][3], acc[i][4]);
            fprintf(js, "},\"indices\":%u", acc[i][5]);
            if (p->material >= 0) fprintf(js, ",\"material\":%d", p->material);
            fprintf(js, ",\"mode\":4}");
        }
        fprintf(js, "]}");
    }
    fprintf(js, "]");
    if (b->skinned) {
        fprintf(js, ",\"skins\":[{\"name\":\"Armature\",\"inverseBindMatrices\":%u,\"skeleton\":%u,\"joints\":[",
                ibm_acc, j0);
        for (int j = 0; j < NJ; j++) fprintf(js, "%s%u", j ? "," : "", j0 + (uint32_t)j);
        fprintf(js, "]}]");
    }
    if (o->texture) {
        fprintf(js, ",\"materials\":[{\"name\":\"Skin\",\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0},"
                    "\"metallicFactor\":0,\"roughnessFactor\":0.8}}");
        if (o->two_primitives)
            fprintf(js, ",{\"name\":\"Cloth\",\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0},"
                        "\"baseColorFactor\":[0.3,0.35,0.8,1],\"metallicFactor\":0,\"roughnessFactor\":0.9}}");
        fprintf(js,
                "],\"textures\":[{\"sampler\":0,\"source\":0}],\"samplers\":[{\"magFilter\":9729,"
                "\"minFilter\":9987,\"wrapS\":10497,\"wrapT\":10497}],\"images\":[{\"name\":\"checker\","
                "\"bufferView\":%u,\"mimeType\":\"image/png\"}]",
                image_view);
    }
    fprintf(js, ",\"accessors\":[%.*s],\"bufferViews\":[%.*s],\"buffers\":[{\"byteLength\":%zu}]}", (int)ot.accs_len,
            ot.accs, (int)ot.views_len, ot.views, ot.len);
    if (fclose(js)) {
        js = NULL;
        goto done;
    }
    js = NULL;
    rc = write_file(path, json, jl, ot.bin, ot.len);
done:
    if (ot.vf) fclose(ot.vf);
    if (ot.af) fclose(ot.af);
    if (js) fclose(js);
    free(ot.views), free(ot.accs), free(ot.bin), free(json);
    return rc;
}

static int fail(int rc, char *why, size_t why_size, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
static int fail(int rc, char *why, size_t why_size, const char *fmt, ...)
{
    if (why && why_size) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(why, why_size, fmt, ap);
        va_end(ap);
    }
    return rc;
}

void ra_info_free(ra_avatar_info_t *info)
{
    if (!info) return;
    free(info->world);
    memset(info, 0, sizeof *info);
}

/* The info: what a viewer shows, in metres, from the generator's data. */
static int fill_info(const build_t *b, const mim_landmark_map_t *map, ra_avatar_info_t *info)
{
    size_t total = 0;
    for (uint32_t i = 0; i < b->np; i++) total += b->prim[i].nv;
    info->world = malloc((3 * total + 1) * sizeof *info->world);
    if (!info->world) return MIM_ENOMEM;
    const int fl = b->vrm0 ? -1 : 1;
    v3 hand = b->J[J_RHAND];
    hand = V(fl * hand.x, hand.y, fl * hand.z);
    double q[4] = {b->sword_q[0], b->sword_q[1], b->sword_q[2], b->sword_q[3]};
    float *w = info->world;
    for (uint32_t i = 0; i < b->np; i++) {
        const prim_t *p = &b->prim[i];
        ra_primitive_info_t *pi = &info->primitive[info->n_primitives++];
        snprintf(pi->mesh_name, sizeof pi->mesh_name, "%s", p->mesh);
        pi->n_vertices = p->nv, pi->n_faces = p->nf, pi->is_body = p->is_body;
        const int local = b->sword_mesh >= 0 && i == b->mesh[b->sword_mesh].first;
        for (uint32_t v = 0; v < p->nv; v++, w += 3) {
            if (!local) {
                memcpy(w, p->pos + 3 * (size_t)v, 3 * sizeof *w);
                continue;
            }
            /* hand joint + (node translation + rotation of the vertex as written) / unit */
            v3 l = vload(p->pos + 3 * (size_t)v);
            l = V((float)(l.x * b->unit), (float)(l.y * b->unit), (float)(l.z * b->unit));
            v3 t = vload(b->sword_t);
            vstore(w, vadd(hand, vscale(vadd(t, qrot(q, l)), 1 / b->unit)));
        }
    }
    info->n_vertices = (uint32_t)total;
    for (int j = 0; j < NJ; j++) vstore(info->joints + 3 * j, V(fl * b->J[j].x, b->J[j].y, fl * b->J[j].z));
    for (uint32_t l = 0; l < RA_N_LANDMARKS && l < map->count; l++) {
        v3 p = vload(b->body.pos + 3 * (size_t)map->vertex[l]);
        vstore(info->landmarks + 3 * l, V(fl * p.x, p.y, fl * p.z));
    }
    info->n_body_welded = b->nb;
    return 0;
}

int ra_write(const ra_options_t *opt, const char *path, ra_avatar_info_t *info, char *why, size_t why_size)
{
    if (info) memset(info, 0, sizeof *info);
    if (!opt || !path) return fail(MIM_EINVAL, why, why_size, "no options or no path");
    if ((int)opt->names < RA_NAMES_MIXAMO || opt->names > RA_NAMES_NONE)
        return fail(MIM_EINVAL, why, why_size, "unknown naming scheme %d", (int)opt->names);
    build_t b;
    memset(&b, 0, sizeof b);
    b.o = opt;
    b.skinned = opt->names != RA_NAMES_NONE;
    b.vrm0 = opt->names == RA_NAMES_VRM0;
    b.unit = opt->centimetres ? 100 : 1;
    b.sword_mesh = -1;
    const uint32_t pose = opt->tpose ? 1 : 0;
    mim_synth_options_t so = {.subjects = opt->subject + 1,
                              .poses = pose + 1,
                              .vertices = opt->vertices ? opt->vertices : 3000,
                              .seed = opt->seed ? opt->seed : 7};
    mim_synth_t *syn = NULL;
    mim_error_t err = {0};
    int rc = mim_synth_create(&syn, &so, &err);
    if (rc) return fail(rc, why, why_size, "%s", mim_error_text(&err));
    const uint32_t nj = mim_synth_n_joints(syn);
    if (nj != NJ) {
        mim_synth_destroy(&syn);
        return fail(MIM_EINVAL, why, why_size, "the synth has %u joints, not %d", nj, NJ);
    }
    for (int j = 0; j < NJ; j++) {
        const char *n = mim_synth_joint_name(syn, (uint32_t)j);
        if (!n || strcmp(n, synth_names[j])) {
            mim_synth_destroy(&syn);
            return fail(MIM_EINVAL, why, why_size, "synth joint %d is '%s', not '%s'", j, n ? n : "?", synth_names[j]);
        }
        b.parent[j] = mim_synth_joint_parent(syn, (uint32_t)j);
    }
    b.nb = mim_synth_n_vertices(syn), b.fb = mim_synth_n_faces(syn), b.faces = mim_synth_faces(syn);
    mim_landmark_map_t map;
    mim_synth_landmarks(syn, &map);
    float jw[3 * NJ];
    geo_t *g = &b.body;
    g->nv = g->vcap = b.nb;
    g->pos = malloc((3 * (size_t)b.nb + 1) * sizeof *g->pos);
    g->jnt = malloc((4 * (size_t)b.nb + 1) * sizeof *g->jnt);
    g->wgt = malloc((4 * (size_t)b.nb + 1) * sizeof *g->wgt);
    if (!g->pos || !g->jnt || !g->wgt) {
        rc = fail(MIM_ENOMEM, why, why_size, "out of memory");
        goto done;
    }
    if ((rc = mim_synth_body(syn, opt->subject, pose, g->pos)) ||
        (rc = mim_synth_joints(syn, opt->subject, pose, jw))) {
        rc = fail(rc, why, why_size, "synth body %u pose %u: %s", opt->subject, pose, mim_strerror(rc));
        goto done;
    }
    for (int j = 0; j < NJ; j++) b.J[j] = vload(jw + 3 * j);
    for (uint32_t v = 0; v < b.nb; v++) b.H = fmax(b.H, g->pos[3 * (size_t)v + 1]);
    make_bones(&b);
    if ((rc = make_body_skin(&b)) || (opt->joint_rings_first && (rc = make_rings(&b))) || (rc = make_body(&b)) ||
        (opt->shells && ((rc = make_eyes(&b)) || (rc = make_boots(&b)))) || (opt->prop && (rc = make_sword(&b)))) {
        rc = fail(rc, why, why_size, "cannot build the avatar: %s", mim_strerror(rc));
        goto done;
    }
    if (b.vrm0) /* turned to face -Z: x and z negated (the sword is in its node's frame) */
        for (uint32_t i = 0; i < b.np; i++) {
            if (b.sword_mesh >= 0 && i == b.mesh[b.sword_mesh].first) continue;
            for (size_t k = 0; k < 3 * (size_t)b.prim[i].nv; k += 3) {
                prim_t *p = &b.prim[i];
                p->pos[k] = -p->pos[k], p->pos[k + 2] = -p->pos[k + 2];
                p->nrm[k] = -p->nrm[k], p->nrm[k + 2] = -p->nrm[k + 2];
            }
        }
    if ((rc = write_glb(&b, path))) {
        rc = fail(rc, why, why_size, "cannot write %s: %s", path, mim_strerror(rc));
        goto done;
    }
    if (info && (rc = fill_info(&b, &map, info))) {
        ra_info_free(info);
        rc = fail(rc, why, why_size, "out of memory");
    }
done:
    for (uint32_t i = 0; i < b.np; i++) prim_free(&b.prim[i]);
    geo_free(&b.body);
    free(b.bn), free(b.vbone);
    mim_synth_destroy(&syn);
    return rc;
}
