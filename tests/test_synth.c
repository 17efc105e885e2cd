/* Tests of mimic synth (synth/mim_synth.h): one closed, well-shaped
 * connectivity; subjects that differ; poses that mean something; exact
 * skeleton ground truth; deterministic, readable files. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "mim_synth.h"
#include "test_support.h"

#include <dirent.h>
#include <ftw.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

/* ---- helpers ---- */

static mim_synth_t *make(uint32_t subjects, uint32_t poses, uint32_t vertices, uint64_t seed)
{
    mim_synth_options_t o = {subjects, poses, vertices, seed, 0, 0, 0};
    mim_synth_t *s = NULL;
    mim_error_t e = {0};
    int rc = mim_synth_create(&s, &o, &e);
    if (rc) fprintf(stderr, "create: %s\n", mim_error_text(&e));
    assert_int_equal(rc, 0);
    assert_non_null(s);
    return s;
}

static float *body(const mim_synth_t *s, uint32_t subject, uint32_t pose)
{
    float *p = malloc((size_t)mim_synth_n_vertices(s) * 3 * sizeof *p);
    assert_non_null(p);
    assert_int_equal(mim_synth_body(s, subject, pose, p), 0);
    return p;
}

static float *joints(const mim_synth_t *s, uint32_t subject, uint32_t pose)
{
    float *j = malloc((size_t)mim_synth_n_joints(s) * 3 * sizeof *j);
    assert_non_null(j);
    assert_int_equal(mim_synth_joints(s, subject, pose, j), 0);
    return j;
}

static int joint_index(const mim_synth_t *s, const char *name)
{
    for (uint32_t j = 0; j < mim_synth_n_joints(s); j++)
        if (!strcmp(mim_synth_joint_name(s, j), name)) return (int)j;
    fail_msg("no joint %s", name);
    return -1;
}

typedef struct {
    double x, y, z;
} v3;
static v3 at(const float *p, uint32_t i) { return (v3){p[3 * i], p[3 * i + 1], p[3 * i + 2]}; }
static v3 sub(v3 a, v3 b) { return (v3){a.x - b.x, a.y - b.y, a.z - b.z}; }
static double dot(v3 a, v3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static v3 cross(v3 a, v3 b) { return (v3){a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
static double norm(v3 a) { return sqrt(dot(a, a)); }
static v3 unit(v3 a)
{
    double n = norm(a);
    return (v3){a.x / n, a.y / n, a.z / n};
}

static double stature(const float *p, uint32_t nv)
{
    double lo = 1e9, hi = -1e9;
    for (uint32_t i = 0; i < nv; i++) lo = fmin(lo, p[3 * i + 1]), hi = fmax(hi, p[3 * i + 1]);
    return hi - lo;
}

static double signed_volume(const float *p, const uint32_t *f, uint32_t nf)
{
    double v = 0;
    for (uint32_t t = 0; t < nf; t++)
        v += dot(at(p, f[3 * t]), cross(at(p, f[3 * t + 1]), at(p, f[3 * t + 2])));
    return v / 6;
}

/* Smallest corner angle (degrees) and area over all triangles. */
static void shape_stats(const float *p, const uint32_t *f, uint32_t nf, double *min_angle, double *min_area)
{
    *min_angle = 180, *min_area = 1e9;
    for (uint32_t t = 0; t < nf; t++) {
        v3 v[3] = {at(p, f[3 * t]), at(p, f[3 * t + 1]), at(p, f[3 * t + 2])};
        for (int i = 0; i < 3; i++) {
            v3 a = sub(v[(i + 1) % 3], v[i]), b = sub(v[(i + 2) % 3], v[i]);
            double c = dot(a, b) / (norm(a) * norm(b));
            double ang = acos(c > 1 ? 1 : c < -1 ? -1 : c) * 180 / M_PI;
            if (!(ang >= *min_angle)) *min_angle = ang; /* NaN counts as degenerate */
        }
        double area = 0.5 * norm(cross(sub(v[1], v[0]), sub(v[2], v[0])));
        if (!(area >= *min_area)) *min_area = area;
    }
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Closed, consistently oriented 2-manifold of genus 0 whose vertex links are
 * single fans. Fails the test with a message otherwise. */
static void check_manifold(const uint32_t *f, uint32_t nf, uint32_t nv)
{
    uint64_t *de = malloc((size_t)nf * 3 * sizeof *de);
    assert_non_null(de);
    for (uint32_t t = 0; t < nf; t++)
        for (int i = 0; i < 3; i++) {
            uint32_t a = f[3 * t + i], b = f[3 * t + (i + 1) % 3];
            assert_true(a < nv);
            assert_true(a != b);
            de[3 * t + i] = (uint64_t)a << 32 | b;
        }
    qsort(de, (size_t)nf * 3, sizeof *de, cmp_u64);
    for (size_t i = 0; i + 1 < (size_t)nf * 3; i++)
        if (de[i] == de[i + 1]) fail_msg("directed edge %u->%u appears twice", (unsigned)(de[i] >> 32), (unsigned)de[i]);
    /* every directed edge has its reverse: each undirected edge in exactly 2 faces */
    for (size_t i = 0; i < (size_t)nf * 3; i++) {
        uint64_t rev = (de[i] & 0xffffffffu) << 32 | de[i] >> 32;
        if (!bsearch(&rev, de, (size_t)nf * 3, sizeof *de, cmp_u64))
            fail_msg("edge %u-%u has one face", (unsigned)(de[i] >> 32), (unsigned)de[i]);
    }
    int64_t E = (int64_t)nf * 3 / 2;
    assert_int_equal((int64_t)nv - E + (int64_t)nf, 2);
    /* vertex links: the opposite edges of a vertex's faces chain into one cycle */
    uint32_t *cnt = calloc(nv + 1, sizeof *cnt), *next = malloc((size_t)nf * 3 * sizeof *next);
    uint32_t *start = calloc(nv + 1, sizeof *start), *fill = malloc((size_t)nv * sizeof *fill);
    uint32_t *from = malloc((size_t)nf * 3 * sizeof *from);
    assert_true(cnt && next && start && fill && from);
    for (uint32_t k = 0; k < nf * 3; k++) cnt[f[k]]++;
    for (uint32_t v = 0; v < nv; v++) {
        assert_true(cnt[v] >= 3); /* every vertex used, none on a sliver fan */
        start[v + 1] = start[v] + cnt[v];
    }
    memcpy(fill, start, nv * sizeof *fill);
    for (uint32_t t = 0; t < nf; t++)
        for (int i = 0; i < 3; i++) {
            uint32_t v = f[3 * t + i], k = fill[v]++;
            from[k] = f[3 * t + (i + 1) % 3];
            next[k] = f[3 * t + (i + 2) % 3];
        }
    for (uint32_t v = 0; v < nv; v++) {
        uint32_t s0 = start[v], n = cnt[v], cur = from[s0], steps = 0;
        do {
            uint32_t k = s0;
            while (k < s0 + n && from[k] != cur) k++;
            if (k == s0 + n) fail_msg("vertex %u: link is not a cycle", v);
            cur = next[k];
            steps++;
        } while (cur != from[s0] && steps <= n);
        if (steps != n) fail_msg("vertex %u: %u faces but its link cycle has %u", v, n, steps);
    }
    free(de), free(cnt), free(next), free(start), free(fill), free(from);
}

static char *tempdir(const char *tag)
{
    char *p = ts_tempdir(tag);
    assert_non_null(p);
    return p;
}

static void rmtree(char *dir)
{
    ts_rmtree(dir);
    free(dir);
}

static char *slurp(const char *dir, const char *name, size_t *len)
{
    char *path = ts_path(dir, name);
    char *b = ts_read_file(path, len);
    free(path);
    return b;
}

/* ---- tests ---- */

static void test_defaults(void **state)
{
    (void)state;
    mim_synth_t *s = NULL;
    assert_int_equal(mim_synth_create(&s, NULL, NULL), 0);
    assert_int_equal(mim_synth_n_subjects(s), 4);
    assert_int_equal(mim_synth_n_poses(s), 12);
    uint32_t nv = mim_synth_n_vertices(s);
    assert_true(nv >= 6300 && nv <= 7700);
    assert_int_equal(mim_synth_n_faces(s), 2 * nv - 4); /* closed genus 0 triangle mesh */
    assert_string_equal(mim_synth_pose_name(s, 0), "rest");
    assert_null(mim_synth_pose_name(s, 12));
    /* designed names are distinct */
    for (uint32_t p = 0; p < 12; p++)
        for (uint32_t q = 0; q < p; q++) assert_string_not_equal(mim_synth_pose_name(s, p), mim_synth_pose_name(s, q));
    assert_true(mim_synth_n_joints(s) >= 15);
    for (uint32_t j = 0; j < mim_synth_n_joints(s); j++) {
        assert_non_null(mim_synth_joint_name(s, j));
        assert_true(mim_synth_joint_parent(s, j) < (int)j);
    }
    assert_int_equal(mim_synth_joint_parent(s, 0), -1);
    assert_null(mim_synth_joint_name(s, mim_synth_n_joints(s)));
    mim_synth_destroy(&s);
    assert_null(s);
    mim_synth_destroy(&s);   /* *s NULL */
    mim_synth_destroy(NULL); /* NULL */

    s = make(1, 20, 2000, 7);
    assert_string_equal(mim_synth_pose_name(s, 12), "random12");
    assert_string_equal(mim_synth_pose_name(s, 19), "random19");
    mim_synth_destroy(&s);
}

static void test_manifold(void **state)
{
    (void)state;
    const uint32_t sizes[] = {7000, 1000, 3000, 20000};
    for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
        mim_synth_t *s = make(1, 1, sizes[i], 1);
        check_manifold(mim_synth_faces(s), mim_synth_n_faces(s), mim_synth_n_vertices(s));
        mim_synth_destroy(&s);
    }
}

static void test_vertex_budget(void **state)
{
    (void)state;
    const uint32_t sizes[] = {1000, 3000, 7000, 20000, 60000};
    for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
        mim_synth_t *s = make(1, 1, sizes[i], 1);
        double r = (double)mim_synth_n_vertices(s) / sizes[i];
        if (r < 0.85 || r > 1.15) fail_msg("asked %u vertices, got %u", sizes[i], mim_synth_n_vertices(s));
        mim_synth_destroy(&s);
    }
}

/* Rest and every pose of every subject: no slivers, no specks. */
static void test_triangle_quality(void **state)
{
    (void)state;
    const uint32_t sizes[] = {7000, 2000, 20000};
    for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
        mim_synth_t *s = make(i == 0 ? 4 : 2, 12, sizes[i], 1 + i);
        const uint32_t *f = mim_synth_faces(s);
        uint32_t nf = mim_synth_n_faces(s);
        double worst_angle = 180, worst_area = 1;
        for (uint32_t sb = 0; sb < mim_synth_n_subjects(s); sb++)
            for (uint32_t p = 0; p < mim_synth_n_poses(s); p++) {
                float *b = body(s, sb, p);
                double a, ar;
                shape_stats(b, f, nf, &a, &ar);
                if (a < 3.0)
                    fail_msg("%u vertices, subject %u pose %s: smallest angle %.2f deg", sizes[i], sb,
                             mim_synth_pose_name(s, p), a);
                if (ar < 5e-7)
                    fail_msg("%u vertices, subject %u pose %s: smallest area %.3g m^2", sizes[i], sb,
                             mim_synth_pose_name(s, p), ar);
                worst_angle = fmin(worst_angle, a), worst_area = fmin(worst_area, ar);
                free(b);
            }
        print_message("%u vertices: smallest angle %.2f deg, smallest area %.3g m^2\n", mim_synth_n_vertices(s),
                      worst_angle, worst_area);
        mim_synth_destroy(&s);
    }
}

static void test_orientation(void **state)
{
    (void)state;
    mim_synth_t *s = make(2, 12, 0, 1);
    for (uint32_t sb = 0; sb < 2; sb++)
        for (uint32_t p = 0; p < 12; p++) {
            float *b = body(s, sb, p);
            double v = signed_volume(b, mim_synth_faces(s), mim_synth_n_faces(s));
            /* outward faces give a positive volume, about a human's (40..130 l) */
            if (!(v > 0.03 && v < 0.15)) fail_msg("subject %u pose %u: volume %.4f m^3", sb, p, v);
            free(b);
        }
    mim_synth_destroy(&s);
}

static void test_determinism(void **state)
{
    (void)state;
    mim_synth_t *a = make(3, 14, 3000, 42), *b = make(3, 14, 3000, 42), *c = make(3, 14, 3000, 43);
    uint32_t nv = mim_synth_n_vertices(a);
    assert_int_equal(nv, mim_synth_n_vertices(b));
    assert_int_equal(nv, mim_synth_n_vertices(c)); /* the connectivity does not depend on the seed */
    assert_memory_equal(mim_synth_faces(a), mim_synth_faces(b), mim_synth_n_faces(a) * 3 * sizeof(uint32_t));
    assert_memory_equal(mim_synth_faces(a), mim_synth_faces(c), mim_synth_n_faces(a) * 3 * sizeof(uint32_t));
    const uint32_t cases[][2] = {{0, 0}, {2, 5}, {1, 13}};
    for (size_t k = 0; k < 3; k++) {
        float *pa = body(a, cases[k][0], cases[k][1]), *pb = body(b, cases[k][0], cases[k][1]);
        float *pc = body(c, cases[k][0], cases[k][1]);
        assert_memory_equal(pa, pb, (size_t)nv * 3 * sizeof(float));
        assert_memory_not_equal(pa, pc, (size_t)nv * 3 * sizeof(float)); /* another seed, other bodies */
        free(pa), free(pb), free(pc);
    }
    mim_synth_destroy(&a), mim_synth_destroy(&b), mim_synth_destroy(&c);
}

static void test_dataset_identical(void **state)
{
    (void)state;
    mim_synth_t *s = make(2, 13, 2000, 5);
    char *d1 = tempdir("synth1"), *d2 = tempdir("synth2");
    mim_error_t e = {0};
    assert_int_equal(mim_synth_write_dataset(s, d1, &e), 0);
    mim_synth_destroy(&s);
    s = make(2, 13, 2000, 5);
    assert_int_equal(mim_synth_write_dataset(s, d2, &e), 0);
    size_t n1, n2;
    char *m = slurp(d1, "manifest.csv", &n1);
    assert_non_null(m);
    int files = 0;
    for (char *line = strtok(m, "\n"); line; line = strtok(NULL, "\n")) {
        if (!strncmp(line, "file,", 5)) continue;
        char name[128];
        assert_int_equal(sscanf(line, "%127[^,]", name), 1);
        char *a = slurp(d1, name, &n1), *b = slurp(d2, name, &n2);
        assert_non_null(a);
        assert_non_null(b);
        assert_int_equal(n1, n2);
        assert_memory_equal(a, b, n1);
        free(a), free(b);
        files++;
    }
    assert_int_equal(files, 26);
    free(m);
    const char *others[] = {"manifest.csv", "landmarks.json"};
    for (int i = 0; i < 2; i++) {
        char *a = slurp(d1, others[i], &n1), *b = slurp(d2, others[i], &n2);
        assert_non_null(a);
        assert_non_null(b);
        assert_int_equal(n1, n2);
        assert_memory_equal(a, b, n1);
        free(a), free(b);
    }
    mim_synth_destroy(&s);
    rmtree(d1), rmtree(d2);
}

static void test_subjects_differ(void **state)
{
    (void)state;
    mim_synth_t *s = make(4, 1, 0, 1);
    uint32_t nv = mim_synth_n_vertices(s);
    int la = joint_index(s, "l_upperarm"), lh = joint_index(s, "l_hand"), lt = joint_index(s, "l_thigh"),
        lf = joint_index(s, "l_foot");
    double h[4], arm[4], leg[4];
    for (uint32_t i = 0; i < 4; i++) {
        float *b = body(s, i, 0), *j = joints(s, i, 0);
        h[i] = stature(b, nv);
        assert_true(h[i] >= 1.50 && h[i] <= 1.95);
        arm[i] = norm(sub(at(j, (uint32_t)lh), at(j, (uint32_t)la)));
        leg[i] = norm(sub(at(j, (uint32_t)lf), at(j, (uint32_t)lt)));
        free(b), free(j);
    }
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < i; k++) {
            if (fabs(h[i] - h[k]) <= 0.02) fail_msg("subjects %d and %d: statures %.3f and %.3f", i, k, h[i], h[k]);
            assert_true(fabs(arm[i] - arm[k]) > 0.002);
            assert_true(fabs(leg[i] - leg[k]) > 0.002);
        }
    /* proportions differ, not only the scale */
    double lo = 1e9, hi = 0;
    for (int i = 0; i < 4; i++) lo = fmin(lo, leg[i] / h[i]), hi = fmax(hi, leg[i] / h[i]);
    assert_true(hi / lo > 1.005);
    mim_synth_destroy(&s);
}

/* Pose 0 is the rest pose: mirror-symmetric body and skeleton, arms 45
 * degrees down; every other designed pose is clearly another pose. */
static void test_poses(void **state)
{
    (void)state;
    mim_synth_t *s = make(2, 12, 2000, 1);
    uint32_t nv = mim_synth_n_vertices(s), nj = mim_synth_n_joints(s);
    mim_landmark_map_t map;
    mim_synth_landmarks(s, &map);
    float *rest = body(s, 0, 0), *jr = joints(s, 0, 0);
    /* symmetric: every vertex has a mirror image (brute force on a small mesh) */
    for (uint32_t i = 0; i < nv; i += 7) {
        v3 m = at(rest, i);
        m.x = -m.x;
        double best = 1e9;
        for (uint32_t k = 0; k < nv; k++) best = fmin(best, norm(sub(at(rest, k), m)));
        if (best > 1e-5) fail_msg("rest vertex %u has no mirror image (%.2g m)", i, best);
    }
    int lu = joint_index(s, "l_upperarm"), le = joint_index(s, "l_forearm");
    v3 d = unit(sub(at(jr, (uint32_t)le), at(jr, (uint32_t)lu)));
    assert_true(fabs(d.x - sqrt(0.5)) < 1e-3 && fabs(d.y + sqrt(0.5)) < 1e-3 && fabs(d.z) < 1e-3);
    /* landmark positions relative to the pelvis joint, per pose */
    float *lm[12];
    for (uint32_t p = 0; p < 12; p++) {
        float *b = body(s, 0, p), *j = joints(s, 0, p);
        lm[p] = malloc(16 * 3 * sizeof(float));
        for (uint32_t k = 0; k < 16; k++)
            for (int c = 0; c < 3; c++) lm[p][3 * k + c] = b[3 * map.vertex[k] + c] - j[c];
        free(b), free(j);
    }
    for (uint32_t p = 0; p < 12; p++)
        for (uint32_t q = 0; q < p; q++) {
            double moved = 0;
            for (uint32_t k = 0; k < 16; k++) moved = fmax(moved, norm(sub(at(lm[p], k), at(lm[q], k))));
            if (moved < 0.10)
                fail_msg("poses %s and %s: landmarks move at most %.3f m", mim_synth_pose_name(s, p),
                         mim_synth_pose_name(s, q), moved);
        }
    /* the same pose on two subjects: same joint rotations, so the same bone directions */
    float *ja = joints(s, 0, 7), *jb = joints(s, 1, 7);
    float *ra = joints(s, 0, 0), *rb = joints(s, 1, 0);
    for (uint32_t j = 1; j < nj; j++) {
        uint32_t p = (uint32_t)mim_synth_joint_parent(s, j);
        v3 da = unit(sub(at(ja, j), at(ja, p))), db = unit(sub(at(jb, j), at(jb, p)));
        v3 a0 = unit(sub(at(ra, j), at(ra, p))), b0 = unit(sub(at(rb, j), at(rb, p)));
        /* the rotation maps rest directions alike: compare angles moved */
        assert_true(fabs(dot(da, a0) - dot(db, b0)) < 0.05);
    }
    for (uint32_t p = 0; p < 12; p++) free(lm[p]);
    free(rest), free(jr), free(ja), free(jb), free(ra), free(rb);
    mim_synth_destroy(&s);
}

static void test_landmarks(void **state)
{
    (void)state;
    mim_synth_t *s = make(4, 1, 0, 3);
    uint32_t nv = mim_synth_n_vertices(s);
    mim_landmark_map_t map;
    mim_synth_landmarks(s, &map);
    assert_int_equal(map.count, 16);
    assert_int_equal(map.topology_vertices, nv);
    mim_error_t e = {0};
    assert_int_equal(mim_landmarks_validate(&map, nv, "synth", &e), 0);
    for (uint32_t k = 0; k < 16; k++) {
        assert_string_equal(map.names[k], mim_landmark_default_names[k]);
        for (uint32_t i = 0; i < k; i++) assert_true(map.vertex[i] != map.vertex[k]);
    }
    /* landmark -> the joint it sits on */
    const char *near[16] = {"head", "chest", "pelvis", "l_upperarm", "r_upperarm", "l_forearm", "r_forearm", "l_hand",
                            "r_hand", "l_thigh", "r_thigh", "l_shin", "r_shin", "l_foot", "r_foot", "spine"};
    for (uint32_t sb = 0; sb < 4; sb++) {
        float *b = body(s, sb, 0), *j = joints(s, sb, 0);
        double top = -1, a1 = 1e9, a2 = 1e9;
        for (uint32_t k = 0; k < 16; k++) {
            v3 v = at(b, map.vertex[k]);
            const char *n = map.names[k];
            if (n[0] == 'l' && n[1] == '_') assert_true(v.x > 0.02);
            if (n[0] == 'r' && n[1] == '_') assert_true(v.x < -0.02);
            if (k == 0) top = v.y;
            else if (v.y >= top) fail_msg("subject %u: %s is above the head landmark", sb, n);
            double dj = norm(sub(v, at(j, (uint32_t)joint_index(s, near[k]))));
            if (dj > 0.2) fail_msg("subject %u: %s is %.3f m from joint %s", sb, n, dj, near[k]);
        }
        /* ankles are the two lowest */
        for (uint32_t k = 0; k < 16; k++) {
            double y = at(b, map.vertex[k]).y;
            if (k == 13 || k == 14) continue;
            a1 = fmin(a1, y);
        }
        a2 = fmax(at(b, map.vertex[13]).y, at(b, map.vertex[14]).y);
        assert_true(a2 < a1);
        /* chest in front, pelvis and spine on the back, mirror pairs mirror */
        assert_true(at(b, map.vertex[1]).z > at(j, 0).z + 0.05);
        assert_true(at(b, map.vertex[2]).z < at(j, 0).z - 0.03);
        assert_true(at(b, map.vertex[15]).z < at(j, 0).z - 0.03);
        for (uint32_t k = 0; k < 16; k++) {
            v3 v = at(b, map.vertex[k]), w = at(b, map.vertex[map.mirror[k]]);
            assert_true(fabs(v.x + w.x) < 1e-4 && fabs(v.y - w.y) < 1e-4 && fabs(v.z - w.z) < 1e-4);
        }
        free(b), free(j);
    }
    mim_synth_destroy(&s);
}

static void test_bone_lengths(void **state)
{
    (void)state;
    mim_synth_t *s = make(3, 30, 1000, 9);
    uint32_t nj = mim_synth_n_joints(s);
    for (uint32_t sb = 0; sb < 3; sb++) {
        float *r = joints(s, sb, 0);
        for (uint32_t p = 1; p < 30; p++) {
            float *q = joints(s, sb, p);
            for (uint32_t j = 1; j < nj; j++) {
                uint32_t pa = (uint32_t)mim_synth_joint_parent(s, j);
                double l0 = norm(sub(at(r, j), at(r, pa))), l1 = norm(sub(at(q, j), at(q, pa)));
                if (fabs(l0 - l1) > 1e-4) fail_msg("subject %u pose %u: bone %s %.5f -> %.5f", sb, p,
                                                   mim_synth_joint_name(s, j), l0, l1);
            }
            /* the root stays over the origin */
            assert_true(fabs(q[0]) < 1e-6 && fabs(q[2]) < 1e-6);
            free(q);
        }
        free(r);
    }
    mim_synth_destroy(&s);
}

/* Knees and elbows bend one way only, in their own plane, within limits. */
static void test_knee_elbow(void **state)
{
    (void)state;
    mim_synth_t *s = make(2, 40, 2000, 11);
    mim_landmark_map_t map;
    mim_synth_landmarks(s, &map);
    const struct {
        const char *a, *b, *c;
        int lm;
        double max_deg;
        int elbow;
        double sign;
    } limbs[] = {
        {"l_thigh", "l_shin", "l_foot", 11, 140, 0, 0},       {"r_thigh", "r_shin", "r_foot", 12, 140, 0, 0},
        {"l_upperarm", "l_forearm", "l_hand", 5, 145, 1, -1}, {"r_upperarm", "r_forearm", "r_hand", 6, 145, 1, 1},
    };
    int bent[4] = {0};
    for (uint32_t sb = 0; sb < 2; sb++)
        for (uint32_t p = 0; p < 40; p++) {
            float *b = body(s, sb, p), *j = joints(s, sb, p);
            for (int k = 0; k < 4; k++) {
                v3 A = at(j, (uint32_t)joint_index(s, limbs[k].a)), B = at(j, (uint32_t)joint_index(s, limbs[k].b)),
                   C = at(j, (uint32_t)joint_index(s, limbs[k].c));
                v3 u = unit(sub(B, A)), v = unit(sub(C, B));
                double ang = acos(fmax(-1, fmin(1, dot(u, v)))) * 180 / M_PI;
                if (ang > limbs[k].max_deg + 0.5)
                    fail_msg("pose %s: %s bent %.1f deg", mim_synth_pose_name(s, p), limbs[k].b, ang);
                if (ang < 10) continue;
                bent[k]++;
                /* landmark direction across the bone: kneecap (front) or outer elbow (axis) */
                v3 l = sub(at(b, map.vertex[limbs[k].lm]), B);
                l = unit(sub(l, (v3){u.x * dot(l, u), u.y * dot(l, u), u.z * dot(l, u)}));
                v3 n = unit(cross(u, v)); /* bend axis */
                if (limbs[k].elbow) {
                    if (limbs[k].sign * dot(n, l) < 0.8)
                        fail_msg("pose %s: %s bends sideways or backwards (%.2f)", mim_synth_pose_name(s, p),
                                 limbs[k].b, dot(n, l));
                } else {
                    v3 w = unit(sub(v, (v3){u.x * dot(v, u), u.y * dot(v, u), u.z * dot(v, u)}));
                    if (dot(w, l) > -0.8)
                        fail_msg("pose %s: %s bends forwards or sideways (%.2f)", mim_synth_pose_name(s, p),
                                 limbs[k].b, dot(w, l));
                }
            }
            free(b), free(j);
        }
    for (int k = 0; k < 4; k++) assert_true(bent[k] > 5); /* the checks did run */
    mim_synth_destroy(&s);
}

/* The files: PLY headers as declared, data equal to mim_synth_body, the
 * manifest and the landmark map, no temporary files left. */
static void test_files(void **state)
{
    (void)state;
    mim_synth_t *s = make(2, 3, 2000, 77);
    uint32_t nv = mim_synth_n_vertices(s), nf = mim_synth_n_faces(s);
    char *dir = tempdir("synthfiles");
    char sub_dir[600];
    snprintf(sub_dir, sizeof sub_dir, "%s/a/b", dir); /* parents are created too */
    mim_error_t e = {0};
    assert_int_equal(mim_synth_write_dataset(s, sub_dir, &e), 0);
    for (uint32_t sb = 0; sb < 2; sb++)
        for (uint32_t p = 0; p < 3; p++) {
            char name[64];
            mim_synth_file_name(sb, p, name, sizeof name);
            size_t len;
            char *d = slurp(sub_dir, name, &len);
            assert_non_null(d);
            char *end = strstr(d, "end_header\n");
            assert_non_null(end);
            size_t hl = (size_t)(end - d) + strlen("end_header\n");
            char *hdr = strndup(d, hl);
            const char *lines[] = {"ply", "format binary_little_endian 1.0", "comment mimic synth seed=77",
                                   NULL /* vertex */, "property float x", "property float y", "property float z",
                                   NULL /* face */, "property list uchar int vertex_indices", "end_header"};
            char *save, *line = strtok_r(hdr, "\n", &save);
            for (int k = 0; k < 10; k++, line = strtok_r(NULL, "\n", &save)) {
                assert_non_null(line);
                unsigned n;
                if (k == 3) assert_true(sscanf(line, "element vertex %u", &n) == 1 && n == nv);
                else if (k == 7) assert_true(sscanf(line, "element face %u", &n) == 1 && n == nf);
                else assert_string_equal(line, lines[k]);
            }
            free(hdr);
            assert_int_equal(len, hl + (size_t)nv * 12 + (size_t)nf * 13);
            float *want = body(s, sb, p);
            assert_memory_equal(d + hl, want, (size_t)nv * 12); /* the test host is little-endian */
            const unsigned char *fb = (const unsigned char *)d + hl + (size_t)nv * 12;
            const uint32_t *faces = mim_synth_faces(s);
            for (uint32_t t = 0; t < nf; t++) {
                assert_int_equal(fb[13 * t], 3);
                uint32_t idx[3];
                memcpy(idx, fb + 13 * t + 1, 12);
                assert_memory_equal(idx, faces + 3 * t, 12);
            }
            free(want), free(d);
        }
    size_t len;
    char *m = slurp(sub_dir, "manifest.csv", &len);
    assert_non_null(m);
    assert_string_equal(m, "file,subject,pose,pose_name\n"
                           "synth_s00_p00.ply,0,0,rest\nsynth_s00_p01.ply,0,1,tpose\nsynth_s00_p02.ply,0,2,arms_up\n"
                           "synth_s01_p00.ply,1,0,rest\nsynth_s01_p01.ply,1,1,tpose\nsynth_s01_p02.ply,1,2,arms_up\n");
    free(m);
    char path[700];
    snprintf(path, sizeof path, "%s/landmarks.json", sub_dir);
    mim_landmark_map_t read, want;
    assert_int_equal(mim_landmarks_read(&read, path, &e), 0);
    mim_synth_landmarks(s, &want);
    assert_int_equal(read.topology_vertices, nv);
    assert_int_equal(read.count, 16);
    assert_memory_equal(read.vertex, want.vertex, 16 * sizeof(uint32_t));
    /* nothing else in the folder: no temporary files */
    DIR *dd = opendir(sub_dir);
    assert_non_null(dd);
    int n = 0;
    for (struct dirent *de; (de = readdir(dd));) {
        if (de->d_name[0] == '.' && (!de->d_name[1] || !strcmp(de->d_name, ".."))) continue;
        assert_null(strstr(de->d_name, ".tmp"));
        n++;
    }
    closedir(dd);
    assert_int_equal(n, 6 + 2);
    mim_synth_destroy(&s);
    rmtree(dir);
}

static void test_errors(void **state)
{
    (void)state;
    mim_synth_t *s = NULL;
    mim_error_t e = {0};
    mim_synth_options_t bad = {1, 1, 100, 1, 0, 0, 0};
    assert_int_equal(mim_synth_create(&s, &bad, &e), MIM_EINVAL);
    assert_null(s);
    assert_non_null(strstr(mim_error_text(&e), "vertices"));
    assert_null(strchr(mim_error_text(&e), '\n'));
    mim_synth_options_t bad2 = {MIM_SYNTH_MAX_SUBJECTS + 1, 1, 0, 1, 0, 0, 0};
    assert_int_equal(mim_synth_create(&s, &bad2, NULL), MIM_EINVAL);
    assert_int_equal(mim_synth_create(NULL, NULL, NULL), MIM_EINVAL);

    s = make(2, 3, 1000, 1);
    float *p = malloc((size_t)mim_synth_n_vertices(s) * 3 * sizeof *p);
    assert_int_equal(mim_synth_body(s, 2, 0, p), MIM_EINVAL);
    assert_int_equal(mim_synth_body(s, 0, 3, p), MIM_EINVAL);
    assert_int_equal(mim_synth_body(s, 0, 0, NULL), MIM_EINVAL);
    assert_int_equal(mim_synth_joints(s, 5, 0, p), MIM_EINVAL);
    assert_int_equal(mim_synth_body(NULL, 0, 0, p), MIM_EINVAL);
    free(p);
    /* a folder where a file is: an error with a one-line message, no crash */
    char *dir = tempdir("synthbad");
    char file[600];
    snprintf(file, sizeof file, "%s/plain", dir);
    FILE *f = fopen(file, "w");
    assert_non_null(f);
    fclose(f);
    mim_error_clear(&e);
    int rc = mim_synth_write_dataset(s, file, &e);
    assert_true(rc < 0);
    assert_non_null(strstr(mim_error_text(&e), "plain"));
    assert_int_equal(mim_synth_write_dataset(s, NULL, NULL), MIM_EINVAL);
    mim_synth_destroy(&s);
    rmtree(dir);

    char name[64];
    mim_synth_file_name(0, 0, name, sizeof name);
    assert_string_equal(name, "synth_s00_p00.ply");
    mim_synth_file_name(3, 11, name, sizeof name);
    assert_string_equal(name, "synth_s03_p11.ply");
    mim_synth_file_name(123, 5, name, sizeof name);
    assert_string_equal(name, "synth_s123_p05.ply");
}

/* The command line through the mimic binary; output copied into the buffers. */
static int run(const char *const *args, char *out, size_t on, char *err, size_t en)
{
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    snprintf(out, on, "%s", o ? o : "");
    snprintf(err, en, "%s", e ? e : "");
    free(o), free(e);
    return rc;
}

static int count_lines(const char *s)
{
    int n = 0;
    for (; *s; s++) n += *s == '\n';
    return n;
}

static void test_cli(void **state)
{
    (void)state;
    if (access(ts_mimic_bin(), X_OK) != 0) skip();
    char out[8192], err[8192];
    const char *help[] = {"synth", "--help", NULL};
    assert_int_equal(run(help, out, sizeof out, err, sizeof err), 0);
    assert_non_null(strstr(out, "--vertices"));
    assert_non_null(strstr(out, "default 7000"));
    const char *bads[][8] = {
        {"synth", NULL},
        {"synth", "--out", "/tmp/x", "--subjects", "0", NULL},
        {"synth", "--out", "/tmp/x", "--poses", "12x", NULL},
        {"synth", "--out", "/tmp/x", "--vertices", "100", NULL},
        {"synth", "--out", "/tmp/x", "--seed", "-1", NULL},
        {"synth", "--out", "/tmp/x", "--bogus", NULL},
        {"synth", "--out", NULL},
    };
    for (size_t i = 0; i < sizeof bads / sizeof bads[0]; i++) {
        assert_int_equal(run(bads[i], out, sizeof out, err, sizeof err), 2);
        assert_int_equal(count_lines(err), 1);
        assert_int_equal(strncmp(err, "mimic synth: ", 13), 0);
    }
    char *dir = tempdir("synthcli");
    char outdir[600];
    snprintf(outdir, sizeof outdir, "%s/data", dir);
    const char *ok[] = {"synth", "--out", outdir, "--subjects", "2", "--poses", "2", "--vertices", "1500", NULL};
    assert_int_equal(run(ok, out, sizeof out, err, sizeof err), 0);
    assert_int_equal(count_lines(out), 1);
    assert_non_null(strstr(out, outdir));
    size_t len;
    char *m = slurp(outdir, "manifest.csv", &len);
    assert_non_null(m);
    assert_int_equal(count_lines(m), 5);
    free(m);
    /* cannot write: exit 1, one line */
    char file[700];
    snprintf(file, sizeof file, "%s/manifest.csv", outdir);
    const char *io[] = {"synth", "--out", file, "--subjects", "1", "--poses", "1", NULL};
    assert_int_equal(run(io, out, sizeof out, err, sizeof err), 1);
    assert_int_equal(count_lines(err), 1);
    rmtree(dir);
}


/* Issue 29: the imitation options. Each subject takes each pose (the rest
 * too) its own way, seeded: the same options give the same bodies; the
 * same pose of two subjects lies further apart in bone direction than
 * without; soft tissue and the registration slide move the surface by
 * millimetres, not the skeleton; bad values are refused in one line. */
static double bone_angle(const float *a, const float *b, const mim_landmark_map_t *m, const char *c, const char *p)
{
    int ci = mim_landmarks_find(m, c), pi = mim_landmarks_find(m, p);
    double u[3], v[3], nu = 0, nv = 0, d = 0;
    for (int k = 0; k < 3; k++) {
        u[k] = a[3 * m->vertex[ci] + k] - a[3 * m->vertex[pi] + k];
        v[k] = b[3 * m->vertex[ci] + k] - b[3 * m->vertex[pi] + k];
        nu += u[k] * u[k], nv += v[k] * v[k], d += u[k] * v[k];
    }
    return acos(fmax(-1, fmin(1, d / sqrt(nu * nv)))) * 180 / M_PI;
}

static void test_imitation(void **state)
{
    (void)state;
    mim_synth_options_t plain = {2, 4, 1500, 3, 0, 0, 0}, imit = plain, again = plain;
    imit.imitation_deg = again.imitation_deg = 3.5;
    imit.tissue_mm = again.tissue_mm = 4, imit.slide_mm = again.slide_mm = 22;
    mim_synth_t *sp = NULL, *si = NULL, *sa = NULL;
    assert_int_equal(mim_synth_create(&sp, &plain, NULL), 0);
    assert_int_equal(mim_synth_create(&si, &imit, NULL), 0);
    assert_int_equal(mim_synth_create(&sa, &again, NULL), 0);
    const uint32_t n = mim_synth_n_vertices(sp);
    float *x = malloc(12 * (size_t)n), *y = malloc(12 * (size_t)n), *z = malloc(12 * (size_t)n), *w = malloc(12 * (size_t)n);
    mim_landmark_map_t m;
    mim_synth_landmarks(sp, &m);
    static const char *const arm[][2] = {{"l_elbow", "l_shoulder"}, {"r_wrist", "r_elbow"}, {"l_knee", "l_hip"}};
    double plain_apart = 0, imit_apart = 0;
    for (uint32_t p = 0; p < 4; p++) {
        assert_int_equal(mim_synth_body(si, 0, p, x), 0);
        assert_int_equal(mim_synth_body(sa, 0, p, y), 0);
        assert_memory_equal(x, y, 12 * (size_t)n); /* seeded */
        assert_int_equal(mim_synth_body(si, 1, p, y), 0);
        assert_int_equal(mim_synth_body(sp, 0, p, z), 0);
        assert_int_equal(mim_synth_body(sp, 1, p, w), 0);
        for (size_t k = 0; k < 3; k++)
            imit_apart += bone_angle(x, y, &m, arm[k][0], arm[k][1]) / 12,
                plain_apart += bone_angle(z, w, &m, arm[k][0], arm[k][1]) / 12;
        /* the rest too: nobody stands in the designed A-pose exactly */
        if (p == 0) {
            double moved = 0;
            for (size_t i = 0; i < 3 * (size_t)n; i++) moved = fmax(moved, fabs(x[i] - z[i]));
            assert_true(moved > 0.01);
        }
    }
    print_message("the same pose, two subjects: bones %.1f deg apart imitating, %.1f deg by one rig\n", imit_apart,
                  plain_apart);
    assert_true(imit_apart > plain_apart + 3);
    mim_synth_destroy(&sp), mim_synth_destroy(&si), mim_synth_destroy(&sa);
    /* out of range: one line each */
    const double bad[][3] = {{-1, 0, 0}, {46, 0, 0}, {0, -1, 0}, {0, 51, 0}, {0, 0, -1}, {0, 0, 51}, {NAN, 0, 0}};
    for (size_t k = 0; k < sizeof bad / sizeof *bad; k++) {
        mim_synth_options_t o = plain;
        o.imitation_deg = bad[k][0], o.tissue_mm = bad[k][1], o.slide_mm = bad[k][2];
        mim_error_t err = {0};
        mim_synth_t *s = NULL;
        assert_int_equal(mim_synth_create(&s, &o, &err), MIM_EINVAL);
        assert_null(s);
        assert_non_null(strstr(err.msg, "must be 0.."));
    }
    free(x), free(y), free(z), free(w);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_defaults),       cmocka_unit_test(test_manifold),
        cmocka_unit_test(test_vertex_budget),  cmocka_unit_test(test_triangle_quality),
        cmocka_unit_test(test_orientation),    cmocka_unit_test(test_determinism),
        cmocka_unit_test(test_dataset_identical), cmocka_unit_test(test_subjects_differ),
        cmocka_unit_test(test_poses),          cmocka_unit_test(test_landmarks),
        cmocka_unit_test(test_bone_lengths),   cmocka_unit_test(test_knee_elbow),
        cmocka_unit_test(test_files),          cmocka_unit_test(test_errors),
        cmocka_unit_test(test_cli),            cmocka_unit_test(test_imitation),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
