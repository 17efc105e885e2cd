/* Landmark-guided registration of the store's connectivity onto another
 * surface (mim_register.h): similarity fit, initial shape by transfer,
 * then non-rigid ICP (nicp.c). */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct mim_reg {
    const mim_xfer_topology_t *topo;
    const mim_landmark_map_t *map;
    mim_reg_options_t opt;
    uint32_t n;
    mim_xfer_solver_t *solver; /* on the landmark vertices: the initial shape's transfer */
    mim__reg_nicp_t *nicp;
    float *moved, *x0f, *tmpl_lm;
    double *frames, *W, *x0, *x, *dist, *data_w;
    uint8_t *region;
};

mim_reg_options_t mim__reg_options(const mim_reg_options_t *in)
{
    mim_reg_options_t o = in ? *in : (mim_reg_options_t){0};
    if (!o.rounds) o.rounds = MIM_REG_DEFAULT_ROUNDS;
    if (!o.stages) o.stages = MIM_REG_DEFAULT_STAGES;
    if (!o.iterations) o.iterations = MIM_REG_DEFAULT_ITERATIONS;
    if (!(o.stiffness_first > 0)) o.stiffness_first = MIM_REG_DEFAULT_STIFFNESS_FIRST;
    if (!(o.stiffness_last > 0)) o.stiffness_last = MIM_REG_DEFAULT_STIFFNESS_LAST;
    if (!(o.landmark_weight > 0)) o.landmark_weight = MIM_REG_DEFAULT_LANDMARK_WEIGHT;
    if (!(o.max_angle_deg > 0)) o.max_angle_deg = MIM_REG_DEFAULT_MAX_ANGLE_DEG;
    if (!(o.max_distance > 0)) o.max_distance = MIM_REG_DEFAULT_MAX_DISTANCE;
    if (!(o.extremity_weight > 0)) o.extremity_weight = o.extremity_weight < 0 ? 1.0 : MIM_REG_DEFAULT_EXTREMITY_WEIGHT;
    return o;
}

void mim_reg_close(mim_reg_t **rp)
{
    if (!rp || !*rp) return;
    mim_reg_t *r = *rp;
    mim_xfer_solver_close(&r->solver);
    mim__reg_nicp_close(&r->nicp);
    free(r->moved), free(r->x0f), free(r->tmpl_lm), free(r->frames), free(r->W), free(r->x0), free(r->x), free(r->dist);
    free(r->data_w), free(r->region);
    free(r);
    *rp = NULL;
}

int mim_reg_open(mim_reg_t **out, const mim_xfer_topology_t *topo, const mim_landmark_map_t *map,
                 const mim_reg_options_t *opt, mim_error_t *err)
{
    if (!out) return mim_error_set(err, MIM_EINVAL, "registration: no output");
    *out = NULL;
    if (!topo || !map) return mim_error_set(err, MIM_EINVAL, "registration: no connectivity or landmark map");
    uint32_t n = mim_xfer_topology_n_vertices(topo);
    int rc = mim_landmarks_validate(map, n, "registration: landmark map", err);
    if (rc) return rc;
    mim_reg_t *r = calloc(1, sizeof *r);
    if (!r) return mim_error_set(err, MIM_ENOMEM, "registration: out of memory");
    r->topo = topo, r->map = map, r->n = n, r->opt = mim__reg_options(opt);
    size_t n3 = (size_t)3 * n;
    r->moved = malloc(n3 * sizeof *r->moved);
    r->x0f = malloc(n3 * sizeof *r->x0f);
    r->tmpl_lm = malloc((size_t)3 * map->count * sizeof *r->tmpl_lm);
    r->frames = malloc(3 * n3 * sizeof *r->frames);
    r->W = malloc(n3 * sizeof *r->W);
    r->x0 = malloc(n3 * sizeof *r->x0);
    r->x = malloc(n3 * sizeof *r->x);
    r->dist = malloc((size_t)n * sizeof *r->dist);
    r->data_w = malloc((size_t)n * sizeof *r->data_w);
    r->region = malloc(n);
    if (!r->moved || !r->x0f || !r->tmpl_lm || !r->frames || !r->W || !r->x0 || !r->x || !r->dist || !r->data_w ||
        !r->region) {
        mim_reg_close(&r);
        return mim_error_set(err, MIM_ENOMEM, "registration: out of memory");
    }
    mim_xfer_solver_options_t so = {0};
    if ((rc = mim_xfer_solver_open(&r->solver, topo, map->vertex, map->count, &so, err)) ||
        (rc = mim__reg_nicp_open(&r->nicp, topo, err))) {
        mim_reg_close(&r);
        return rc;
    }
    *out = r;
    return 0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* The handedness of a landmark skeleton (issue 29): the sign of
 * det(left, up, forward), left from the right shoulders and hips to the
 * left ones, up from the pelvis to the chest, forward from the spine
 * (back) to the chest (front); 0 without those landmarks or when the three
 * are not clearly a frame: |det| under MIN_FRAME of their lengths'
 * product. Upright bodies give 0.45-0.55 (mh-bodies), 0.2-0.46 (synth);
 * a deep bow brings up and forward together and the spine in front of the
 * chest (mh-bodies' pose 10: -0.16 to +0.03), whose sign is noise: at
 * 1e-3, mh_s05_p10 was refused as a mirror image. A body and its mirror
 * image have opposite signs. */
#define MIN_FRAME 0.25
static int handedness(const mim_landmark_map_t *map, const float *lm)
{
    static const char *const want[7] = {"l_shoulder", "r_shoulder", "l_hip", "r_hip", "pelvis", "chest", "spine"};
    int at[7];
    for (int k = 0; k < 7; k++)
        if ((at[k] = mim_landmarks_find(map, want[k])) < 0) return 0;
    double L[3], U[3], F[3];
    for (int c = 0; c < 3; c++) {
        L[c] = lm[3 * at[0] + c] - lm[3 * at[1] + c] + lm[3 * at[2] + c] - lm[3 * at[3] + c];
        U[c] = lm[3 * at[5] + c] - lm[3 * at[4] + c];
        F[c] = lm[3 * at[5] + c] - lm[3 * at[6] + c];
    }
    const double det = L[0] * (U[1] * F[2] - U[2] * F[1]) - L[1] * (U[0] * F[2] - U[2] * F[0]) +
                       L[2] * (U[0] * F[1] - U[1] * F[0]);
    const double size = sqrt((L[0] * L[0] + L[1] * L[1] + L[2] * L[2]) * (U[0] * U[0] + U[1] * U[1] + U[2] * U[2]) *
                             (F[0] * F[0] + F[1] * F[1] + F[2] * F[2]));
    return !(size > 0) || fabs(det) < MIN_FRAME * size ? 0 : det > 0 ? 1 : -1;
}

/* The enclosed volume of a mesh (divergence theorem; positive for faces
 * wound outwards, whatever the mesh's holes make of it). */
static double signed_volume(const uint32_t *faces, uint32_t nf, const float *x)
{
    double v = 0;
    for (uint32_t f = 0; f < nf; f++) {
        const float *a = x + 3 * (size_t)faces[3 * f], *b = x + 3 * (size_t)faces[3 * f + 1], *c = x + 3 * (size_t)faces[3 * f + 2];
        v += a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) - a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
             a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
    }
    return v / 6;
}

/* How much registration stretched the template (issue 29: surface
 * distance hides sliding): per body region (a vertex's nearest landmark:
 * head; torso; arms; hands; legs; feet), the rms of the log of each edge's
 * length against the moved template's, in percent. */
/* Each vertex's body region (mim_reg_region_names): its nearest landmark's
 * on the shape x. */
static void vertex_regions(const mim_reg_t *r, const float *x, uint8_t *region)
{
    static const char *const region_of[][2] = {
        {"head", "head"},     {"chest", "torso"},    {"pelvis", "torso"},   {"spine", "torso"},  {"l_shoulder", "torso"},
        {"r_shoulder", "torso"}, {"l_elbow", "arms"}, {"r_elbow", "arms"},  {"l_wrist", "hands"}, {"r_wrist", "hands"},
        {"l_hip", "legs"},    {"r_hip", "legs"},     {"l_knee", "legs"},    {"r_knee", "legs"},  {"l_ankle", "feet"},
        {"r_ankle", "feet"}};
    int lm_region[MIM_LANDMARKS_MAX];
    for (uint32_t l = 0; l < r->map->count; l++) {
        lm_region[l] = 1; /* another landmark: the torso */
        for (size_t k = 0; k < sizeof region_of / sizeof *region_of; k++)
            if (!strcmp(r->map->names[l], region_of[k][0]))
                for (int g = 0; g < MIM_REG_REGIONS; g++)
                    if (!strcmp(region_of[k][1], mim_reg_region_names[g])) lm_region[l] = g;
    }
    for (uint32_t v = 0; v < r->n; v++) {
        const float *p = x + 3 * (size_t)v;
        double best = INFINITY;
        int g = 1;
        for (uint32_t l = 0; l < r->map->count; l++) {
            const float *q = x + 3 * (size_t)r->map->vertex[l];
            double d = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]);
            if (d < best) best = d, g = lm_region[l];
        }
        region[v] = (uint8_t)g;
    }
}

/* The rms change of edge lengths per region from the moved template to
 * out, % (regions by the moved template's landmarks). */
static void distortion(const mim_reg_t *r, const float *moved, const float *out, double pct[MIM_REG_REGIONS])
{
    double ss[MIM_REG_REGIONS] = {0};
    uint64_t cnt[MIM_REG_REGIONS] = {0};
    vertex_regions(r, moved, r->region);
    for (uint32_t v = 0; v < r->n; v++) {
        const int g = r->region[v];
        uint32_t nn = 0;
        const uint32_t *nb = mim_xfer_neighbors(r->topo, v, &nn);
        for (uint32_t k = 0; k < nn; k++) {
            const uint32_t w = nb[k];
            if (w < v) continue; /* each edge once */
            double a = 0, b = 0;
            for (int c = 0; c < 3; c++) {
                a += pow((double)moved[3 * (size_t)v + c] - moved[3 * (size_t)w + c], 2);
                b += pow((double)out[3 * (size_t)v + c] - out[3 * (size_t)w + c], 2);
            }
            if (!(a > 0) || !(b > 0)) continue;
            const double e = 0.5 * log(b / a);
            ss[g] += e * e, cnt[g]++;
        }
    }
    for (int g = 0; g < MIM_REG_REGIONS; g++) pct[g] = cnt[g] ? 100 * sqrt(ss[g] / (double)cnt[g]) : 0;
}

const char *const mim_reg_region_names[MIM_REG_REGIONS] = {"head", "torso", "arms", "hands", "legs", "feet"};

int mim_reg_run(mim_reg_t *r, const float *tmpl, const mim_mesh_t *target, const float *target_landmarks,
                const char *origin, float *out, mim_reg_report_t *report, mim_error_t *err)
{
    double t0 = mim_now();
    if (!origin) origin = "target";
    if (!r || !tmpl || !target || !target_landmarks || !out)
        return mim_error_set(err, MIM_EINVAL, "%s: registration needs a template, a target and its landmarks", origin);
    mim_reg_report_t rep = {0};
    const mim_landmark_map_t *map = r->map;
    uint32_t n = r->n, count = map->count;
    int rc = mim_landmarks_check(target_landmarks, NULL, count, origin, -1, err);
    if (rc) return rc;
    mim__reg_surface_t surface;
    if ((rc = mim__reg_surface_open(&surface, target, r->opt.pieces ? 2 : 1, origin, err))) return rc;

    /* 1. The template's landmarks onto the target's: place, orientation, size. */
    for (uint32_t l = 0; l < count; l++)
        memcpy(r->tmpl_lm + 3 * l, tmpl + 3 * (size_t)map->vertex[l], 3 * sizeof(float));
    mim_reg_similarity_t sim;
    mim_error_t sub = {0};
    if ((rc = mim_reg_similarity_fit(r->tmpl_lm, target_landmarks, count, &sim, &sub))) {
        rc = mim_error_set(err, rc, "%s: landmarks: %s", origin, mim_error_text(&sub));
        goto done;
    }
    rep.scale = sim.scale;
    mim_reg_similarity_apply(&sim, tmpl, n, r->moved);
    mim_xfer_frames(r->topo, r->moved, r->frames);
    mim_xfer_encode(r->topo, r->moved, r->frames, r->W);
    /* a mirror image cannot be registered (no rotation takes a body onto
     * it): refused before the solve turns the template inside out */
    const int hand_t = handedness(map, r->tmpl_lm), hand_g = handedness(map, target_landmarks);
    if (hand_t && hand_g && hand_t != hand_g) {
        rc = mim_error_set(err, MIM_EFORMAT,
                           "%s: its landmarks are a mirror image of a body (left and right swapped?): "
                           "registration needs them on the body's own sides",
                           origin);
        goto done;
    }

    /* 2. Initial shape: the moved template as its own avatar, transferred
     * into the target's landmark positions (seed 000, eq. 3); then ICP;
     * rounds times. */
    mim_xfer_options_t xo = {0};
    double t1 = t0;
    for (uint32_t round = 0; round < r->opt.rounds; round++) {
        /* From the second round on, the frames come from the last result,
         * which is in the target's pose: a template far from that pose
         * (a sitting one for a high kick) gets a second, closer start. */
        if (round > 0) mim_xfer_frames_d(r->topo, r->x, r->frames);
        if ((rc = mim_xfer_transfer(r->solver, r->W, n, r->frames, target_landmarks, count, &xo, r->x0f, NULL,
                                    &sub))) {
            rc = mim_error_set(err, rc, "%s: initial shape: %s", origin, mim_error_text(&sub));
            goto done;
        }
        for (size_t i = 0; i < (size_t)3 * n; i++)
            r->x0[i] = r->x0f[i];
        if (round == 0) t1 = mim_now(), rep.seconds_initial = t1 - t0;

        /* 3. Non-rigid ICP onto the surface. */
        uint32_t steps = 0;
        if (r->opt.no_icp) {
            memcpy(r->x, r->x0, (size_t)3 * n * sizeof *r->x);
            break;
        }
        /* the hands and feet trust the initial shape's correspondence
         * (MIM_REG_DEFAULT_EXTREMITY_WEIGHT), by the initial shape's regions */
        vertex_regions(r, r->x0f, r->region);
        for (uint32_t i = 0; i < n; i++)
            r->data_w[i] = r->region[i] == MIM_REG_REGION_HANDS || r->region[i] == MIM_REG_REGION_FEET
                               ? r->opt.extremity_weight
                               : 1.0;
        if ((rc = mim__reg_nicp_run(r->nicp, &r->opt, &surface, map->vertex, target_landmarks, count, r->x0, r->data_w, r->x,
                                    &steps, &rep.rejected, &sub))) {
            rc = mim_error_set(err, rc, "%s: %s", origin, mim_error_text(&sub));
            goto done;
        }
        rep.iterations += steps;
    }
    for (size_t i = 0; i < (size_t)3 * n; i++)
        out[i] = (float)r->x[i];
    rep.seconds_icp = mim_now() - t1;
    if ((rc = mim_body_check(out, n, origin, err))) goto done;
    /* a result turned inside out or flattened is no body: its enclosed
     * volume against the moved template's */
    {
        uint32_t nf = 0;
        const uint32_t *faces = mim_xfer_topology_faces(r->topo, &nf);
        const double vt = signed_volume(faces, nf, r->moved), vo = signed_volume(faces, nf, out);
        rep.volume_ratio = vt != 0 ? vo / vt : NAN;
        if (vt != 0 && !(rep.volume_ratio >= MIM_REG_MIN_VOLUME_RATIO)) {
            rc = mim_error_set(err, MIM_ETOPOLOGY,
                               "%s: the registered body encloses %.0f%% of its template's volume (at least %.0f%% "
                               "needed): the surface is flat, degenerate or inside out",
                               origin, 100 * rep.volume_ratio, 100 * MIM_REG_MIN_VOLUME_RATIO);
            goto done;
        }
    }
    distortion(r, r->moved, out, rep.distortion_pct);

    /* Figures: surface distance of every vertex, landmark residuals. */
    mim__reg_hit_t *hits = malloc((size_t)n * sizeof *hits);
    if (!hits) {
        rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory", origin);
        goto done;
    }
    if ((rc = mim__reg_surface_closest(&surface, out, n, hits, err))) {
        free(hits);
        goto done;
    }
    double sum = 0.0;
    for (uint32_t i = 0; i < n; i++)
        r->dist[i] = sqrt(hits[i].d2) * 1000.0, sum += r->dist[i];
    free(hits);
    rep.mean_mm = sum / n;
    qsort(r->dist, n, sizeof *r->dist, cmp_double);
    rep.p95_mm = r->dist[(size_t)floor(0.95 * (n - 1))];
    rep.max_mm = r->dist[n - 1];
    rep.n_landmarks = count;
    for (uint32_t l = 0; l < count; l++) {
        const float *a = out + 3 * (size_t)map->vertex[l], *b = target_landmarks + 3 * l;
        double d = sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
        rep.landmark_mm[l] = d * 1000.0;
        rep.landmark_mean_mm += rep.landmark_mm[l] / count;
        if (rep.landmark_mm[l] > rep.landmark_max_mm) rep.landmark_max_mm = rep.landmark_mm[l];
    }
    rep.seconds = mim_now() - t0;
done:
    mim__reg_surface_close(&surface);
    if (!rc && report) *report = rep;
    return rc;
}
