/* Where the avatar is far from its proxy, it follows the body's segments
 * (mim_register.h, issue 28).
 *
 * The binding (bind.c) carries each avatar vertex on its closest proxy
 * triangle, its offset in the local frame there. Close to the proxy that
 * is exact and smooth; far from it (a fist bound to an open hand, long
 * hair, a boot's sole, a sword) neighbouring avatar vertices land on
 * triangles that turn differently (two fingers), and the offset swings
 * with each: slivers and faces turned inside out. So a vertex at distance
 * d from the proxy takes a share alpha(d) = smoothstep(near, far, d) of
 * linear blend skinning instead: the rigid motions of the segments under
 * its closest point (the proxy's segment weights there), each fitted
 * every frame to the proxy's own vertices of that segment (least squares,
 * the polar factor of their cross-covariance). The hands follow their
 * segment so always (in the measure of the hand's weight, so the wrist
 * blends): the vest does not track fingers, and a hand registered onto
 * another hand (fists onto open hands, fingers onto the wrong fingers)
 * leaves the proxy's fingers folded, which a transfer turns wildly. Where
 * registration crushed the proxy elsewhere (mim_reg_crushed), the avatar
 * follows the segments as much as the crush. A piece of the avatar that
 * lies mostly far from the proxy (p90 of its distances over `far`: a
 * sword, a hat, a prop) follows one segment rigidly: the segment its rig
 * gives it, else the one under its nearest vertex. */
#include "mim_register.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define SAMPLES_PER_SEGMENT 64u
#define SEGMENT_SAMPLE_WEIGHT 0.6f /* a proxy vertex samples its segment when that segment weighs at least this */

void mim_reg_follow_free(mim_reg_follow_t *f)
{
    if (!f) return;
    free(f->vertex), free(f->alpha), free(f->bone), free(f->weight), free(f->rest), free(f->samples);
    memset(f, 0, sizeof *f);
}

static uint32_t uf_find(uint32_t *p, uint32_t x)
{
    while (p[x] != x) x = p[x] = p[p[x]];
    return x;
}

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static double smoothstep(double a, double b, double x)
{
    if (x <= a) return 0;
    if (x >= b) return 1;
    double t = (x - a) / (b - a);
    return t * t * (3 - 2 * t);
}

int mim_reg_follow_build(const mim_reg_binding_t *b, const uint32_t *proxy_faces, const mim_xfer_skin_t *proxy_skin,
                         const mim_mesh_t *avatar, const int *rig_segment, const mim_reg_follow_options_t *opt,
                         mim_reg_follow_t *out, mim_error_t *err)
{
    if (!out) return mim_error_set(err, MIM_EINVAL, "follow: no output");
    memset(out, 0, sizeof *out);
    if (!b || !proxy_faces || !proxy_skin || !avatar || avatar->n_vertices != b->n_vertices)
        return mim_error_set(err, MIM_EINVAL, "follow: needs the binding, the proxy's skin and the avatar it binds");
    const double near = opt && opt->near > 0 ? opt->near : MIM_REG_FOLLOW_NEAR;
    const double far = opt && opt->far > near ? opt->far : fmax(near * 2, MIM_REG_FOLLOW_FAR);
    const double max_far_share = opt && opt->max_far_share > 0 ? opt->max_far_share : MIM_REG_FOLLOW_MAX_FAR_SHARE;
    const uint32_t rigid_mask = opt && opt->rigid ? (opt->rigid == MIM_REG_FOLLOW_RIGID_NONE ? 0 : opt->rigid)
                                                  : MIM_REG_FOLLOW_RIGID_DEFAULT;
    const uint32_t n = avatar->n_vertices, np = b->n_proxy_vertices, G = MIM_SEGMENTS;
    float *dist = malloc((size_t)n * sizeof *dist), *segw = calloc((size_t)n * G, sizeof *segw);
    uint32_t *wmap = malloc((size_t)n * sizeof *wmap), *parent = NULL, *piece_start = NULL, *piece_v = NULL;
    float *piece_d = NULL;
    mim_mesh_t welded = {0};
    int rc = dist && segw && wmap ? 0 : mim_error_set(err, MIM_ENOMEM, "follow: out of memory");

    /* how crushed the proxy is where each avatar vertex is bound */
    const float *unreliable = opt ? opt->crush : NULL;
    float *bad = !rc && unreliable ? calloc((size_t)n + 1, sizeof *bad) : NULL;
    if (unreliable && !bad) rc = mim_error_set(err, MIM_ENOMEM, "follow: out of memory");
    /* each vertex's distance from the proxy and the segment weights under its closest point */
    for (uint32_t e = 0; !rc && e < n; e++) {
        const uint32_t v = b->vertex[e], *fv = proxy_faces + 3 * (size_t)b->face[e];
        if (bad)
            bad[v] = (1 - b->bary[2 * e] - b->bary[2 * e + 1]) * unreliable[fv[0]] + b->bary[2 * e] * unreliable[fv[1]] +
                     b->bary[2 * e + 1] * unreliable[fv[2]];
        const float *o = b->offset + 3 * (size_t)e, u = b->bary[2 * e], w = b->bary[2 * e + 1];
        dist[v] = sqrtf(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
        const float share[3] = {1 - u - w, u, w};
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < MIM_XFER_SKIN_INFLUENCES; k++) {
                const mim_xfer_skin_t *sk = proxy_skin + fv[c];
                if (sk->bone[k] < G && share[c] > 0) segw[(size_t)v * G + sk->bone[k]] += share[c] * sk->weight[k];
            }
    }

    /* the avatar's pieces (after welding its split copies) */
    if (!rc) rc = mim_reg_weld(avatar, 0, &welded, wmap, err);
    const uint32_t nw = welded.n_vertices;
    if (!rc && !(parent = malloc(((size_t)nw + 1) * sizeof *parent)))
        rc = mim_error_set(err, MIM_ENOMEM, "follow: out of memory");
    if (!rc) {
        for (uint32_t i = 0; i < nw; i++) parent[i] = i;
        for (uint32_t f = 0; f < welded.n_faces; f++)
            for (int k = 1; k < 3; k++) {
                uint32_t a = uf_find(parent, welded.faces[3 * f]), c = uf_find(parent, welded.faces[3 * f + k]);
                if (a != c) parent[a] = c;
            }
        /* vertices grouped by piece (root of their welded vertex) */
        piece_start = calloc((size_t)nw + 2, sizeof *piece_start);
        piece_v = malloc(((size_t)n + 1) * sizeof *piece_v);
        piece_d = malloc(((size_t)n + 1) * sizeof *piece_d);
        if (!piece_start || !piece_v || !piece_d) rc = mim_error_set(err, MIM_ENOMEM, "follow: out of memory");
    }
    float *alpha_all = NULL;
    int *one_bone = NULL;
    if (!rc && (!(alpha_all = malloc((size_t)n * sizeof *alpha_all)) || !(one_bone = malloc((size_t)n * sizeof *one_bone))))
        rc = mim_error_set(err, MIM_ENOMEM, "follow: out of memory");
    if (!rc) {
        for (uint32_t v = 0; v < n; v++) piece_start[uf_find(parent, wmap[v]) + 1]++;
        for (uint32_t r = 0; r < nw; r++) piece_start[r + 1] += piece_start[r];
        uint32_t *fill = malloc(((size_t)nw + 1) * sizeof *fill);
        if (!fill) rc = mim_error_set(err, MIM_ENOMEM, "follow: out of memory");
        for (uint32_t r = 0; !rc && r < nw; r++) fill[r] = piece_start[r];
        for (uint32_t v = 0; !rc && v < n; v++) piece_v[fill[uf_find(parent, wmap[v])]++] = v;
        free(fill);
    }
    uint32_t far_vertices = 0, far_pieces = 0, pieces = 0;
    for (uint32_t r = 0; !rc && r < nw; r++) {
        const uint32_t a = piece_start[r], z = piece_start[r + 1];
        if (a == z) continue;
        pieces++;
        for (uint32_t k = a; k < z; k++) piece_d[k] = dist[piece_v[k]];
        qsort(piece_d + a, z - a, sizeof *piece_d, cmp_float);
        const float p90 = piece_d[a + (uint32_t)(0.9 * (double)(z - a - 1))];
        int bone = -1;
        if (p90 > far) { /* a prop: one segment, rigidly */
            far_pieces++, far_vertices += z - a;
            uint32_t votes[MIM_SEGMENTS] = {0}, nearest = piece_v[a];
            for (uint32_t k = a; k < z; k++) {
                uint32_t v = piece_v[k];
                if (rig_segment && rig_segment[v] >= 0 && rig_segment[v] < (int)G) votes[rig_segment[v]]++;
                if (dist[v] < dist[nearest]) nearest = v;
            }
            for (uint32_t g = 0; g < G; g++)
                if (votes[g] && (bone < 0 || votes[g] > votes[bone])) bone = (int)g;
            if (bone < 0)
                for (uint32_t g = 0; g < G; g++)
                    if (bone < 0 || segw[(size_t)nearest * G + g] > segw[(size_t)nearest * G + (uint32_t)bone])
                        bone = (int)g;
        }
        for (uint32_t k = a; k < z; k++) {
            uint32_t v = piece_v[k];
            one_bone[v] = bone;
            alpha_all[v] = bone >= 0 ? 1.0f : (float)smoothstep(near, far, dist[v]);
            if (bad && bad[v] > alpha_all[v]) alpha_all[v] = bad[v];
            /* the rigid segments (the hands): as much as their weight here, fading across the wrist */
            int rigid = -1; /* the heaviest rigid segment here */
            for (uint32_t g = 0; g < G; g++)
                if ((rigid_mask & (1u << g)) && segw[(size_t)v * G + g] > 0 &&
                    (rigid < 0 || segw[(size_t)v * G + g] > segw[(size_t)v * G + (uint32_t)rigid]))
                    rigid = (int)g;
            const float rigid_w = rigid >= 0 ? segw[(size_t)v * G + (uint32_t)rigid] : 0;
            if (bone < 0 && rigid_w > alpha_all[v]) {
                /* that segment's own motion, blended with the surface's, not with its neighbours': a toe
                 * weighted to the foot and the shin (or, by a careless rig, the other foot) would
                 * collapse between their turns */
                alpha_all[v] = fminf(rigid_w, 1.0f);
                for (uint32_t g = 0; g < G; g++)
                    if (g != (uint32_t)rigid) segw[(size_t)v * G + g] = 0;
            }
        }
    }
    out->pieces = pieces, out->far_pieces = far_pieces, out->far_vertices = far_vertices;
    if (!rc && (double)far_vertices > max_far_share * n)
        rc = mim_error_set(err, MIM_ETOPOLOGY,
                           "%u of its %u vertices (%u of %u pieces) lie over %.0f mm from the registered body: one "
                           "body is expected, with props and shells at most %.0f%% of it",
                           far_vertices, n, far_pieces, pieces, far * 1e3, 100 * max_far_share);

    /* the entries: vertices that take some of the segments' motion */
    uint32_t m = 0;
    for (uint32_t v = 0; !rc && v < n; v++) m += alpha_all[v] > 0;
    if (!rc) {
        out->n_vertices = n, out->n_entries = m;
        out->vertex = malloc(((size_t)m + 1) * sizeof *out->vertex);
        out->alpha = malloc(((size_t)m + 1) * sizeof *out->alpha);
        out->bone = malloc(((size_t)m + 1) * sizeof *out->bone);
        out->weight = malloc(((size_t)m + 1) * sizeof *out->weight);
        out->rest = malloc(((size_t)3 * m + 1) * sizeof *out->rest);
        out->samples = malloc(((size_t)G * SAMPLES_PER_SEGMENT + 1) * sizeof *out->samples);
        if (!out->vertex || !out->alpha || !out->bone || !out->weight || !out->rest || !out->samples)
            rc = mim_error_set(err, MIM_ENOMEM, "follow: out of memory");
    }
    for (uint32_t v = 0, e = 0; !rc && v < n; v++) {
        if (!(alpha_all[v] > 0)) continue;
        out->vertex[e] = v, out->alpha[e] = alpha_all[v];
        memcpy(out->rest + 3 * (size_t)e, avatar->positions + 3 * (size_t)v, 3 * sizeof(float));
        memset(out->bone[e], 0, sizeof out->bone[e]);
        memset(out->weight[e], 0, sizeof out->weight[e]);
        if (one_bone[v] >= 0) {
            out->bone[e][0] = (uint8_t)one_bone[v], out->weight[e][0] = 1;
        } else { /* the four heaviest segments under it, normalised */
            float *w = segw + (size_t)v * G, sum = 0;
            for (int k = 0; k < 4; k++) {
                int best = -1;
                for (uint32_t g = 0; g < G; g++)
                    if (w[g] > 0 && (best < 0 || w[g] > w[best])) best = (int)g;
                if (best < 0) break;
                out->bone[e][k] = (uint8_t)best, out->weight[e][k] = w[best], sum += w[best];
                w[best] = -w[best]; /* taken */
            }
            for (int k = 0; k < 4; k++) out->weight[e][k] = sum > 0 ? out->weight[e][k] / sum : (k == 0);
        }
        e++;
    }
    /* each segment's sample of proxy vertices, evenly over the vertices it dominates */
    for (uint32_t g = 0; !rc && g < G; g++) {
        uint32_t count = 0;
        for (uint32_t i = 0; i < np; i++)
            count += proxy_skin[i].bone[0] == g && proxy_skin[i].weight[0] >= SEGMENT_SAMPLE_WEIGHT &&
                     !(unreliable && unreliable[i] > 0);
        uint32_t stride = count > SAMPLES_PER_SEGMENT ? (count + SAMPLES_PER_SEGMENT - 1) / SAMPLES_PER_SEGMENT : 1, k = 0;
        out->sample_start[g] = out->n_samples;
        for (uint32_t i = 0; i < np && out->n_samples - out->sample_start[g] < SAMPLES_PER_SEGMENT; i++)
            if (proxy_skin[i].bone[0] == g && proxy_skin[i].weight[0] >= SEGMENT_SAMPLE_WEIGHT &&
                !(unreliable && unreliable[i] > 0) && k++ % stride == 0)
                out->samples[out->n_samples++] = i;
    }
    out->sample_start[G] = out->n_samples;
    out->n_proxy_vertices = np;
    free(alpha_all), free(one_bone), free(bad);
    free(dist), free(segw), free(wmap), free(parent), free(piece_start), free(piece_v), free(piece_d);
    mim_mesh_free(&welded);
    if (rc) {
        uint32_t pc = out->pieces, fp = out->far_pieces, fv = out->far_vertices;
        mim_reg_follow_free(out);
        out->pieces = pc, out->far_pieces = fp, out->far_vertices = fv;
    }
    return rc;
}

/* The rotation R (row-major) that best takes the rest samples onto the
 * posed ones, from H = sum (y - cy)(x - cx)^T (row-major): Horn's
 * quaternion method (1987), the unit eigenvector of the largest eigenvalue
 * of a symmetric 4x4, which stays a rotation when the samples are near a
 * plane or a line (a hand's few samples), where a polar decomposition
 * degenerates. 0 when the eigen solver fails. */
static int best_rotation(const double H[9], double R[9])
{
    /* S[a][b] = sum x_a y_b = H[b][a] */
    const double Sxx = H[0], Sxy = H[3], Sxz = H[6], Syx = H[1], Syy = H[4], Syz = H[7], Szx = H[2], Szy = H[5],
                 Szz = H[8];
    double N[16] = {Sxx + Syy + Szz, Syz - Szy,        Szx - Sxz,        Sxy - Syx,
                    Syz - Szy,       Sxx - Syy - Szz,  Sxy + Syx,        Szx + Sxz,
                    Szx - Sxz,       Sxy + Syx,        -Sxx + Syy - Szz, Syz + Szy,
                    Sxy - Syx,       Szx + Sxz,        Syz + Szy,        -Sxx - Syy + Szz};
    double ev[4];
    if (LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', 4, N, 4, ev) != 0) return 0;
    /* ascending eigenvalues: the last column is the largest's vector */
    double w = N[3], x = N[7], y = N[11], z = N[15], l = sqrt(w * w + x * x + y * y + z * z);
    if (!(l > 0)) return 0;
    w /= l, x /= l, y /= l, z /= l;
    const double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - z * w),     2 * (x * z + y * w),
                         2 * (x * y + z * w),     1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                         2 * (x * z - y * w),     2 * (y * z + x * w),     1 - 2 * (x * x + y * y)};
    memcpy(R, r, sizeof r);
    return 1;
}

void mim_reg_follow_apply(const mim_reg_follow_t *f, const float *proxy_rest, const float *proxy_posed, float *out)
{
    if (!f->n_entries) return;
    double R[MIM_SEGMENTS][9], cr[MIM_SEGMENTS][3], cp[MIM_SEGMENTS][3];
    for (uint32_t g = 0; g < MIM_SEGMENTS; g++) {
        const uint32_t a = f->sample_start[g], z = f->sample_start[g + 1];
        double H[9] = {0}, sr[3] = {0}, sp[3] = {0};
        for (uint32_t k = a; k < z; k++)
            for (int c = 0; c < 3; c++)
                sr[c] += proxy_rest[3 * (size_t)f->samples[k] + c], sp[c] += proxy_posed[3 * (size_t)f->samples[k] + c];
        const double inv = z > a ? 1.0 / (z - a) : 0;
        for (int c = 0; c < 3; c++) cr[g][c] = sr[c] * inv, cp[g][c] = sp[c] * inv;
        for (uint32_t k = a; k < z; k++) {
            const float *x = proxy_rest + 3 * (size_t)f->samples[k], *y = proxy_posed + 3 * (size_t)f->samples[k];
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++) H[3 * r + c] += (y[r] - cp[g][r]) * (x[c] - cr[g][c]);
        }
        if (z - a < 4 || !best_rotation(H, R[g])) { /* too few samples to fit (a hand all crushed): its parent's motion */
            const int up = mim_segment_parent(g); /* parents come first: already fitted */
            if (up >= 0) {
                memcpy(R[g], R[up], sizeof R[g]);
                memcpy(cr[g], cr[up], sizeof cr[g]);
                memcpy(cp[g], cp[up], sizeof cp[g]);
            } else {
                memset(R[g], 0, sizeof R[g]);
                R[g][0] = R[g][4] = R[g][8] = 1;
                if (z == a) memset(cr[g], 0, sizeof cr[g]), memset(cp[g], 0, sizeof cp[g]);
            }
        }
    }
    /* each segment's motion as one affine map x -> M [x 1] (3 x 4, float):
     * an entry's blend is then the weighted sum of its segments' maps */
    float M[MIM_SEGMENTS][12];
    for (uint32_t g = 0; g < MIM_SEGMENTS; g++)
        for (int r = 0; r < 3; r++) {
            double t = cp[g][r];
            for (int c = 0; c < 3; c++) M[g][4 * r + c] = (float)R[g][3 * r + c], t -= R[g][3 * r + c] * cr[g][c];
            M[g][4 * r + 3] = (float)t;
        }
    for (uint32_t e = 0; e < f->n_entries; e++) {
        const float *p = f->rest + 3 * (size_t)e;
        float B[12] = {0};
        for (int k = 0; k < 4; k++) {
            const float w = f->weight[e][k];
            if (!(w > 0)) continue;
            const float *m = M[f->bone[e][k]];
            for (int i = 0; i < 12; i++) B[i] += w * m[i];
        }
        float *x = out + 3 * (size_t)f->vertex[e];
        const float a = f->alpha[e];
        for (int r = 0; r < 3; r++) {
            const float L = B[4 * r] * p[0] + B[4 * r + 1] * p[1] + B[4 * r + 2] * p[2] + B[4 * r + 3];
            x[r] = (1 - a) * x[r] + a * L;
        }
    }
}

void mim_reg_stretch(const uint32_t *faces, uint32_t n_faces, const float *rest, const float *posed, double limit,
                     double *share_over, double *max_ratio)
{
    uint64_t over = 0, counted = 0;
    double worst = 0;
    for (uint32_t f = 0; f < n_faces; f++) {
        double face_worst = 0;
        int degenerate = 0;
        for (int k = 0; k < 3; k++) {
            const float *a = rest + 3 * (size_t)faces[3 * f + k], *b = rest + 3 * (size_t)faces[3 * f + (k + 1) % 3];
            const float *A = posed + 3 * (size_t)faces[3 * f + k], *B = posed + 3 * (size_t)faces[3 * f + (k + 1) % 3];
            double r2 = 0, p2 = 0;
            for (int c = 0; c < 3; c++) r2 += (double)(b[c] - a[c]) * (b[c] - a[c]), p2 += (double)(B[c] - A[c]) * (B[c] - A[c]);
            if (!(r2 > 1e-16)) degenerate = 1;
            else face_worst = fmax(face_worst, sqrt(p2 / r2));
        }
        if (degenerate) continue; /* a zero-length edge at rest has no ratio */
        counted++;
        over += face_worst > limit;
        worst = fmax(worst, face_worst);
    }
    *share_over = counted ? (double)over / (double)counted : 0;
    *max_ratio = worst;
}

static double tri_area(const float *x, const uint32_t *t)
{
    const float *a = x + 3 * (size_t)t[0], *b = x + 3 * (size_t)t[1], *c = x + 3 * (size_t)t[2];
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    return 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

uint32_t mim_reg_crushed(const uint32_t *faces, uint32_t n_faces, uint32_t n_vertices, const float *proxy,
                         const float *tmpl, double scale, float *crush)
{
    memset(crush, 0, (size_t)n_vertices * sizeof *crush);
    if (!(scale > 0) || !isfinite(scale)) scale = 1;
    for (uint32_t f = 0; f < n_faces; f++) {
        const uint32_t *t = faces + 3 * (size_t)f;
        const double at = tri_area(tmpl, t) * scale * scale, ap = tri_area(proxy, t);
        if (!(at > 0)) continue;
        const double off = ap > 0 ? fabs(log(ap / at)) : INFINITY;
        const float c = (float)smoothstep(MIM_REG_CRUSH_FROM, MIM_REG_CRUSH_TO, isfinite(off) ? off : 1e9);
        for (int k = 0; k < 3; k++)
            if (c > crush[t[k]]) crush[t[k]] = c;
    }
    /* fading out ring by ring: each pass lets a vertex take its neighbour's less one step */
    const float step = 1.0f / (MIM_REG_CRUSH_RINGS + 1);
    for (uint32_t ring = 0; ring < MIM_REG_CRUSH_RINGS; ring++)
        for (uint32_t f = 0; f < n_faces; f++) {
            const uint32_t *t = faces + 3 * (size_t)f;
            float m = fmaxf(crush[t[0]], fmaxf(crush[t[1]], crush[t[2]])) - step;
            for (int k = 0; k < 3; k++)
                if (m > crush[t[k]]) crush[t[k]] = m;
        }
    uint32_t count = 0;
    for (uint32_t i = 0; i < n_vertices; i++) count += crush[i] > 0;
    return count;
}
