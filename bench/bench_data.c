/* Shared bench helpers: timing statistics, pooled errors and the datasets
 * (bench_data.h). */
#include "bench_data.h"
#include "mim_register.h"
#include "mim_io.h"

#include "mim_synth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

double bench_quantile(double *v, int k, double q)
{
    qsort(v, (size_t)k, sizeof *v, cmp_d);
    int i = (int)floor(q * (k - 1));
    return v[i < 0 ? 0 : i >= k ? k - 1 : i];
}

double bench_load_average(void)
{
    double load = -1;
    FILE *f = fopen("/proc/loadavg", "r");
    if (f) {
        if (fscanf(f, "%lf", &load) != 1) load = -1;
        fclose(f);
    }
    return load;
}

double bench_median(double *v, int k)
{
    qsort(v, (size_t)k, sizeof *v, cmp_d);
    return k % 2 ? v[k / 2] : 0.5 * (v[k / 2 - 1] + v[k / 2]);
}

int bench_err_init(bench_err_t *e)
{
    memset(e, 0, sizeof *e);
    e->hist = calloc(BENCH_ERR_BINS, sizeof *e->hist);
    return e->hist ? 0 : -1;
}

void bench_err_free(bench_err_t *e)
{
    free(e->hist);
    memset(e, 0, sizeof *e);
}

void bench_err_add_mm(bench_err_t *e, double mm)
{
    e->sum += mm;
    long b = (long)(mm * 100.0);
    if (b >= BENCH_ERR_BINS || b < 0)
        b = BENCH_ERR_BINS - 1;
    e->hist[b]++;
    e->count++;
}

void bench_err_add(bench_err_t *e, const float *x, const float *truth, uint32_t n, double *e_mm)
{
    for (uint32_t i = 0; i < n; i++) {
        double dx = x[3 * i] - truth[3 * i], dy = x[3 * i + 1] - truth[3 * i + 1],
               dz = x[3 * i + 2] - truth[3 * i + 2];
        double mm = 1000.0 * sqrt(dx * dx + dy * dy + dz * dz);
        bench_err_add_mm(e, mm);
        if (e_mm)
            e_mm[i] = mm;
    }
}

double bench_err_mean(const bench_err_t *e)
{
    return e->count ? e->sum / (double)e->count : NAN;
}

double bench_err_p95(const bench_err_t *e)
{
    uint64_t want = (uint64_t)ceil(0.95 * (double)e->count), acc = 0;
    for (long b = 0; b < BENCH_ERR_BINS; b++) {
        acc += e->hist[b];
        if (acc >= want)
            return (b + 0.5) / 100.0;
    }
    return INFINITY;
}

int bench_load_synth(bench_dataset_t *d, uint32_t subjects, uint32_t poses, uint32_t vertices)
{
    return bench_load_imitation(d, subjects, poses, vertices, 0);
}

int bench_load_imitation(bench_dataset_t *d, uint32_t subjects, uint32_t poses, uint32_t vertices, double sigma_deg)
{
    mim_error_t err = {0};
    mim_synth_t *s = NULL;
    const char *tissue = getenv("BENCH_TISSUE_MM"), *slide = getenv("BENCH_SLIDE_MM"); /* calibration only */
    const char *seed = getenv("BENCH_SEED"); /* calibration only */
    mim_synth_options_t o = {.subjects = subjects, .poses = poses, .vertices = vertices, .seed = seed ? strtoull(seed, NULL, 10) : 1,
                             .imitation_deg = sigma_deg,
                             .tissue_mm = sigma_deg > 0 ? (tissue ? atof(tissue) : BENCH_TISSUE_MM) : 0,
                             .slide_mm = sigma_deg > 0 ? (slide ? atof(slide) : BENCH_SLIDE_MM) : 0};
    memset(d, 0, sizeof *d);
    if (mim_synth_create(&s, &o, &err)) {
        fprintf(stderr, "synth: %s\n", mim_error_text(&err));
        return -1;
    }
    d->name = sigma_deg > 0 ? "imitation" : "synth";
    d->n = mim_synth_n_vertices(s);
    d->n_faces = mim_synth_n_faces(s);
    d->subjects = subjects;
    d->poses = poses;
    d->faces = malloc(3 * (size_t)d->n_faces * sizeof *d->faces);
    memcpy(d->faces, mim_synth_faces(s), 3 * (size_t)d->n_faces * sizeof *d->faces);
    mim_synth_landmarks(s, &d->map);
    d->pos = calloc((size_t)subjects * poses, sizeof *d->pos);
    for (uint32_t k = 0; k < subjects * poses; k++) {
        d->pos[k] = malloc(3 * (size_t)d->n * sizeof(float));
        mim_synth_body(s, k / poses, k % poses, d->pos[k]);
    }
    mim_synth_destroy(&s);
    return 0;
}

int bench_load_mh(bench_dataset_t *d, const char *dir)
{
    mim_error_t err = {0};
    char path[4200];
    memset(d, 0, sizeof *d);
    snprintf(path, sizeof path, "%s/landmarks.json", dir);
    FILE *probe = fopen(path, "r");
    if (!probe)
        return 1;
    fclose(probe);
    if (mim_landmarks_read(&d->map, path, &err)) {
        fprintf(stderr, "mh-bodies: %s\n", mim_error_text(&err));
        return -1;
    }
    d->name = "mh-bodies";
    d->subjects = 8;
    d->poses = 12;
    d->pos = calloc((size_t)d->subjects * d->poses, sizeof *d->pos);
    for (uint32_t k = 0; k < d->subjects * d->poses; k++) {
        mim_mesh_t m = {0};
        snprintf(path, sizeof path, "%s/mh_s%02u_p%02u.ply", dir, k / d->poses, k % d->poses);
        if (mim_io_read_mesh(path, &m, &err)) {
            fprintf(stderr, "mh-bodies: %s\n", mim_error_text(&err));
            bench_dataset_free(d);
            return -1;
        }
        if (k == 0) {
            d->n = m.n_vertices;
            d->n_faces = m.n_faces;
            d->faces = malloc(3 * (size_t)m.n_faces * sizeof *d->faces);
            memcpy(d->faces, m.faces, 3 * (size_t)m.n_faces * sizeof *d->faces);
        } else if (m.n_vertices != d->n || m.n_faces != d->n_faces ||
                   memcmp(m.faces, d->faces, 3 * (size_t)m.n_faces * sizeof *d->faces)) {
            fprintf(stderr, "mh-bodies: %s: connectivity differs\n", path);
            mim_mesh_free(&m);
            bench_dataset_free(d);
            return -1;
        }
        d->pos[k] = m.positions;
        m.positions = NULL;
        mim_mesh_free(&m);
    }
    return 0;
}

void bench_dataset_free(bench_dataset_t *d)
{
    if (d->pos)
        for (uint32_t k = 0; k < d->subjects * d->poses; k++)
            free(d->pos[k]);
    free(d->pos);
    free(d->faces);
    memset(d, 0, sizeof *d);
}

const char *const bench_region_names[BENCH_REGIONS] = {"head", "hands", "feet", "torso", "limbs"};

int bench_region_of_segment(uint32_t segment)
{
    static const uint8_t region[MIM_SEGMENTS] = {
        BENCH_REGION_TORSO, BENCH_REGION_TORSO, BENCH_REGION_HEAD,  BENCH_REGION_TORSO, BENCH_REGION_TORSO,
        BENCH_REGION_LIMBS, BENCH_REGION_LIMBS, BENCH_REGION_LIMBS, BENCH_REGION_LIMBS, BENCH_REGION_HANDS,
        BENCH_REGION_HANDS, BENCH_REGION_LIMBS, BENCH_REGION_LIMBS, BENCH_REGION_LIMBS, BENCH_REGION_LIMBS,
        BENCH_REGION_FEET,  BENCH_REGION_FEET};
    return segment < MIM_SEGMENTS ? region[segment] : BENCH_REGION_LIMBS;
}

const char *bench_mh_dir(char *buf, size_t size)
{
    const char *env = getenv("MIMIC_SHARED_DATA");
    if (env) {
        snprintf(buf, size, "%s/mh-bodies", env);
    } else {
        snprintf(buf, size, "%s", __FILE__);
        char *slash = strrchr(buf, '/');
        if (slash)
            *slash = 0;
        strncat(buf, "/../../shared/data/mh-bodies", size - strlen(buf) - 1);
    }
    return buf;
}

int bench_pose_spread(const bench_dataset_t *d, double *rms, double *p10, double *p90)
{
    const uint32_t L = d->map.count;
    int ch[MIM_LANDMARK_BONES], pa[MIM_LANDMARK_BONES];
    const char *missing;
    if (mim_landmark_skeleton(&d->map, ch, pa, &missing)) return -1;
    size_t cap = (size_t)d->poses * d->subjects * d->subjects / 2 + 1, n = 0, all_n = 0;
    double *pair = malloc(cap * sizeof *pair), all = 0;
    float a[3 * MIM_LANDMARKS_MAX], b[3 * MIM_LANDMARKS_MAX], bm[3 * MIM_LANDMARKS_MAX];
    for (uint32_t p = 1; pair && p < d->poses; p++) /* the rest pose is everybody's own */
        for (uint32_t s1 = 0; s1 < d->subjects; s1++)
            for (uint32_t s2 = s1 + 1; s2 < d->subjects; s2++) {
                for (uint32_t l = 0; l < L; l++)
                    for (int c = 0; c < 3; c++) {
                        a[3 * l + c] = d->pos[s1 * d->poses + p][3 * (size_t)d->map.vertex[l] + c];
                        b[3 * l + c] = d->pos[s2 * d->poses + p][3 * (size_t)d->map.vertex[l] + c];
                    }
                mim_reg_similarity_t sim;
                if (mim_reg_similarity_fit(b, a, L, &sim, NULL)) continue;
                sim.scale = 1; /* rigid: only the bones' directions count */
                mim_reg_similarity_apply(&sim, b, L, bm);
                double ss = 0;
                for (int k = 0; k < MIM_LANDMARK_BONES; k++) {
                    double u[3], v[3], nu = 0, nv = 0, dot = 0;
                    for (int c = 0; c < 3; c++) {
                        u[c] = a[3 * ch[k] + c] - a[3 * pa[k] + c], v[c] = bm[3 * ch[k] + c] - bm[3 * pa[k] + c];
                        nu += u[c] * u[c], nv += v[c] * v[c], dot += u[c] * v[c];
                    }
                    double ang = acos(fmax(-1, fmin(1, dot / sqrt(nu * nv)))) * 180 / M_PI;
                    ss += ang * ang, all += ang * ang, all_n++;
                }
                pair[n++] = sqrt(ss / MIM_LANDMARK_BONES);
            }
    if (!n) {
        free(pair);
        return -1;
    }
    *rms = sqrt(all / (double)all_n);
    *p10 = bench_quantile(pair, (int)n, 0.10);
    *p90 = bench_quantile(pair, (int)n, 0.90);
    free(pair);
    return 0;
}

void bench_sets_init(bench_sets_t *s)
{
    memset(s, 0, sizeof *s);
    s->vertices = 7000;
    s->imitation_deg = BENCH_IMITATION_DEG;
}

int bench_sets_arg(bench_sets_t *s, int argc, char **argv, int *i)
{
    if (!strcmp(argv[*i], "--vertices") && *i + 1 < argc)
        s->vertices = (uint32_t)strtoul(argv[++*i], NULL, 10);
    else if (!strcmp(argv[*i], "--mh") && *i + 1 < argc)
        s->mh = argv[++*i];
    else if (!strcmp(argv[*i], "--no-mh"))
        s->no_mh = 1;
    else if (!strcmp(argv[*i], "--imitation") && *i + 1 < argc)
        s->imitation_deg = strtod(argv[++*i], NULL);
    else if (!strcmp(argv[*i], "--no-imitation"))
        s->imitation_deg = 0;
    else
        return 0;
    return 1;
}

int bench_sets_run(bench_sets_t *s, uint32_t subjects, uint32_t poses, bench_set_fn fn, void *user)
{
    bench_dataset_t d = {0};
    if (bench_load_synth(&d, subjects, poses, s->vertices))
        return 1;
    int rc = fn(&d, user);
    bench_dataset_free(&d);
    if (!rc && s->imitation_deg > 0) {
        /* the same subjects imitating the poses (issue 29): defaults are chosen here */
        if (bench_load_imitation(&d, subjects, poses, s->vertices, s->imitation_deg)) return 1;
        double rms = 0, p10 = 0, p90 = 0;
        fflush(stdout);
        if (!bench_pose_spread(&d, &rms, &p10, &p90))
            printf("\nimitation: synth's subjects, each taking each pose its own way (every joint axis %.1f deg, "
                   "one in four looser), with soft tissue (%.0f mm) and a registered store's slide (%.0f mm): the "
                   "same pose differs between two subjects by %.1f deg rms per bone after rigid alignment (pairs "
                   "p10 %.1f, p90 %.1f; real people: 11.4, 7.6, 18.2)\n",
                   s->imitation_deg, BENCH_TISSUE_MM, BENCH_SLIDE_MM, rms, p10, p90);
        fflush(stdout);
        rc = fn(&d, user);
        bench_dataset_free(&d);
    }
    if (rc || s->no_mh)
        return rc ? 1 : 0;
    const char *mh = s->mh ? s->mh : bench_mh_dir(s->mh_buf, sizeof s->mh_buf);
    int lr = bench_load_mh(&d, mh);
    if (lr > 0) {
        printf("\nmh-bodies: %s not found, skipped\n", mh);
        return 0;
    }
    if (lr < 0)
        return 1;
    rc = fn(&d, user);
    bench_dataset_free(&d);
    return rc ? 1 : 0;
}
