/* Canonical proportions (index/proportions.c): with the landmark skeleton
 * the index takes its angles on the templates' mean segment lengths, so a
 * body of other proportions in a template's pose answers that template at
 * distance 0, and more often with landmarks lost too; completion is
 * unchanged; the blob keeps the skeleton and refuses a damaged one; bad
 * skeletons and options are refused at build. */
#include "mim_index.h"
#include "mim_synth.h"
#include "test_support.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void mim__index_seal(unsigned char *p, size_t len);

enum { S = 3, P = 12, N = S * P, L = 16 };

typedef struct {
    float lm[N][3 * L];
    uint64_t ids[N];
    char names[2][N][8];
    const char *subjects[N], *poses[N];
    mim_landmark_map_t map;
    int32_t parent[L];
} set_t;

static set_t *make_set(void)
{
    set_t *s = calloc(1, sizeof *s);
    mim_synth_options_t so = {.subjects = S, .poses = P, .vertices = 1500, .seed = 11};
    mim_synth_t *syn = NULL;
    assert_int_equal(mim_synth_create(&syn, &so, NULL), 0);
    mim_synth_landmarks(syn, &s->map);
    assert_int_equal(s->map.count, L);
    float *body = malloc(12 * mim_synth_n_vertices(syn));
    for (uint32_t t = 0; t < N; t++) {
        assert_int_equal(mim_synth_body(syn, t / P, t % P, body), 0);
        for (uint32_t l = 0; l < L; l++) memcpy(s->lm[t] + 3 * l, body + 3 * s->map.vertex[l], 12);
        s->ids[t] = 1 + t;
        snprintf(s->names[0][t], 8, "s%u", t / P), snprintf(s->names[1][t], 8, "p%u", t % P);
        s->subjects[t] = s->names[0][t], s->poses[t] = s->names[1][t];
    }
    assert_int_equal(mim_index_skeleton(&s->map, s->parent), 0);
    free(body);
    mim_synth_destroy(&syn);
    return s;
}

static mim_index_t *build(const set_t *s, int proportions)
{
    mim_index_input_t in = {N, L, &s->lm[0][0], s->ids, s->subjects, s->poses, s->map.mirror, s->parent};
    mim_index_options_t o = {.features = 30, .proportions = proportions};
    mim_index_report_t rep;
    mim_index_t *ix = NULL;
    assert_int_equal(mim_index_build(&ix, &in, &o, &rep, NULL), 0);
    assert_int_equal(rep.canonical, proportions == MIM_INDEX_PROPORTIONS_BODY ? 0 : 1);
    return ix;
}

/* The frame's arms and legs (each bone from its parent, parents first)
 * `factor` times as long, then turned about y by 0.7 rad, scaled by 1.3
 * and moved: another body in the same pose, elsewhere. */
static void other_body(const set_t *s, const float *in, double factor, float *out)
{
    static const char *const limbs[] = {"l_elbow", "r_elbow", "l_wrist", "r_wrist", "l_knee",
                                        "r_knee",  "l_ankle", "r_ankle", NULL};
    double x[3 * L];
    for (int i = 0; i < 3 * L; i++) x[i] = in[i];
    for (int k = 0; limbs[k]; k++) {
        const int j = mim_landmarks_find(&s->map, limbs[k]), p = s->parent[j];
        double was[3];
        for (int c = 0; c < 3; c++) was[c] = (double)in[3 * j + c] - in[3 * p + c];
        /* the parent already moved: keep the bone's direction from there */
        for (int c = 0; c < 3; c++) x[3 * j + c] = x[3 * p + c] + factor * was[c];
    }
    const double a = 0.7, co = cos(a), si = sin(a);
    for (int l = 0; l < L; l++) {
        const double px = x[3 * l], pz = x[3 * l + 2];
        out[3 * l] = (float)(1.3 * (co * px + si * pz) + 0.4);
        out[3 * l + 1] = (float)(1.3 * x[3 * l + 1] - 0.2);
        out[3 * l + 2] = (float)(1.3 * (-si * px + co * pz) + 1.1);
    }
}

/* Bodies with 1.5 times the limbs answer their template at distance 0 on
 * canonical proportions; on the bodies' proportions they are far from it.
 * With an elbow and a knee lost, their pose is still right, and their own
 * template is found far more often than on the bodies' proportions. */
static void test_other_proportions(void **st)
{
    (void)st;
    set_t *s = make_set();
    mim_index_t *canon = build(s, 0), *body = build(s, MIM_INDEX_PROPORTIONS_BODY);
    const int elbow = mim_landmarks_find(&s->map, "l_elbow"), knee = mim_landmarks_find(&s->map, "r_knee");
    double worst_canon = 0, least_body = INFINITY;
    uint32_t found_masked = 0, found_masked_body = 0;
    for (uint32_t t = 0; t < N; t++) {
        float q[3 * L];
        other_body(s, s->lm[t], 1.5, q);
        mim_index_answer_t a;
        mim_index_hit_t h;
        assert_int_equal(mim_index_query(canon, q, NULL, NULL, &a, &h, NULL), 0);
        assert_int_equal(h.id, s->ids[t]);
        worst_canon = fmax(worst_canon, h.distance);
        assert_int_equal(mim_index_query(body, q, NULL, NULL, &a, &h, NULL), 0);
        least_body = fmin(least_body, h.distance);
        /* lost landmarks: the bones beyond them keep their directions */
        uint8_t present[L];
        memset(present, 1, L);
        present[elbow] = present[knee] = 0;
        q[3 * elbow] = NAN; /* never read */
        assert_int_equal(mim_index_query(canon, q, present, NULL, &a, &h, NULL), 0);
        assert_int_equal(a.missing, 2);
        found_masked += h.id == s->ids[t];
        assert_string_equal(h.pose, s->poses[t]);
        assert_int_equal(mim_index_query(body, q, present, NULL, &a, &h, NULL), 0);
        found_masked_body += h.id == s->ids[t];
    }
    print_message("canonical: worst distance %.2g rad; body: least %.3f rad; 2 lost: %u of %u found (body: %u)\n",
                  worst_canon, least_body, found_masked, N, found_masked_body);
    assert_true(worst_canon < 1e-3);
    assert_true(least_body > 0.05); /* the bodies' proportions do see the limbs */
    /* with an elbow lost, the wrist's distance from the shoulder is the
     * frame's own, scaled by its proportions as a whole (proportions.c):
     * near, not exact, for a body whose limbs alone are longer */
    assert_true(found_masked > found_masked_body + N / 4);
    mim_index_close(&canon);
    mim_index_close(&body);
    free(s);
}

/* Completion in an index of canonical angles (its Gaussians see frames as
 * given): present landmarks come back as given, and a lost wrist and
 * ankle of a training body come back near where they were, in the body's
 * own scale (the frame scaled by 1.3). */
static void test_completion_scale(void **st)
{
    (void)st;
    set_t *s = make_set();
    mim_index_t *ix = build(s, 0);
    const int wrist = mim_landmarks_find(&s->map, "r_wrist"), ankle = mim_landmarks_find(&s->map, "l_ankle");
    double worst = 0;
    for (uint32_t t = 0; t < N; t++) {
        float q[3 * L], out[3 * L];
        other_body(s, s->lm[t], 1.0, q); /* the body itself, turned, scaled and moved */
        const float truth_w[3] = {q[3 * wrist], q[3 * wrist + 1], q[3 * wrist + 2]};
        const float truth_a[3] = {q[3 * ankle], q[3 * ankle + 1], q[3 * ankle + 2]};
        uint8_t present[L];
        memset(present, 1, L);
        present[wrist] = present[ankle] = 0;
        q[3 * wrist] = q[3 * ankle + 1] = NAN;
        assert_int_equal(mim_index_complete(ix, q, present, out, NULL, NULL), 0);
        for (int l = 0; l < L; l++)
            if (present[l]) assert_memory_equal(out + 3 * l, q + 3 * l, 12);
        double ew = 0, ea = 0;
        for (int c = 0; c < 3; c++) {
            ew += (out[3 * wrist + c] - truth_w[c]) * (out[3 * wrist + c] - truth_w[c]);
            ea += (out[3 * ankle + c] - truth_a[c]) * (out[3 * ankle + c] - truth_a[c]);
        }
        worst = fmax(worst, fmax(sqrt(ew), sqrt(ea)));
    }
    print_message("completion of a lost wrist and ankle: worst %.3f m (bodies 1.3 times synth's)\n", worst);
    assert_true(worst < 0.10);
    mim_index_close(&ix);
    free(s);
}

/* The blob keeps the skeleton: the loaded and in-place indexes answer as
 * the built one; a skeleton that is not a tree, or a length that is not
 * positive, is refused with one line even with every checksum right. */
static void test_blob(void **st)
{
    (void)st;
    set_t *s = make_set();
    mim_index_t *ix = build(s, 0), *back = NULL;
    void *blob = NULL;
    size_t len = 0;
    assert_int_equal(mim_index_save(ix, &blob, &len, NULL), 0);
    assert_int_equal(mim_index_load(&back, blob, len, NULL), 0);
    mim_index_info_t info;
    mim_index_get_info(back, &info);
    assert_int_equal(info.canonical, 1);
    float q[3 * L];
    other_body(s, s->lm[5], 1.5, q);
    mim_index_answer_t a1, a2;
    mim_index_hit_t h1, h2;
    assert_int_equal(mim_index_query(ix, q, NULL, NULL, &a1, &h1, NULL), 0);
    assert_int_equal(mim_index_query(back, q, NULL, NULL, &a2, &h2, NULL), 0);
    assert_int_equal(h1.id, h2.id);
    assert_true(h1.distance == h2.distance);
    mim_index_close(&back);
    /* the parent table in the head */
    unsigned char *p = NULL;
    assert_int_equal(posix_memalign((void **)&p, 64, len), 0);
    unsigned char *at = memmem(blob, len, s->parent, sizeof s->parent);
    assert_non_null(at);
    const size_t off = (size_t)(at - (unsigned char *)blob);
    const int elbow = mim_landmarks_find(&s->map, "l_elbow"), wrist = mim_landmarks_find(&s->map, "l_wrist");
    struct {
        size_t off;
        int32_t value;
        const char *says;
    } cases[] = {
        {off + 4 * (size_t)elbow, wrist, "not a tree"},     /* elbow <-> wrist: a cycle */
        {off + 4 * (size_t)elbow, -1, "not a tree"},        /* two roots */
        {off + 4 * (size_t)elbow, L, "not a tree"},         /* out of range */
        {off + 4 * L + 4 * (size_t)wrist, 0, "length"},     /* length 0 */
        {off + 4 * L + 4 * (size_t)wrist, -1082130432, "length"}, /* -1.0f */
        {off - 8, L + 1, "proportions for"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        memcpy(p, blob, len);
        memcpy(p + cases[k].off, &cases[k].value, 4);
        mim__index_seal(p, len);
        mim_error_t err = {0};
        mim_index_t *bad = NULL;
        assert_int_equal(mim_index_open_in_place(&bad, p, len, &err), MIM_EFORMAT);
        assert_null(bad);
        if (!strstr(err.msg, cases[k].says)) fail_msg("case %zu: %s", k, err.msg);
        assert_null(strchr(err.msg, '\n'));
    }
    free(p), free(blob);
    mim_index_close(&ix);
    free(s);
}

/* A parent table that is not a tree, an unknown proportions option and a
 * map without the 16 default landmarks. */
static void test_refused(void **st)
{
    (void)st;
    set_t *s = make_set();
    int32_t parent[L];
    memcpy(parent, s->parent, sizeof parent);
    const int head = mim_landmarks_find(&s->map, "head"), chest = mim_landmarks_find(&s->map, "chest");
    parent[chest] = head; /* chest <-> head */
    mim_index_input_t in = {N, L, &s->lm[0][0], s->ids, s->subjects, s->poses, s->map.mirror, parent};
    mim_index_t *ix = NULL;
    mim_error_t err = {0};
    assert_int_equal(mim_index_build(&ix, &in, NULL, NULL, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "not a tree"));
    assert_null(ix);
    in.parent = s->parent;
    mim_index_options_t o = {.proportions = 3};
    mim_error_clear(&err);
    assert_int_equal(mim_index_build(&ix, &in, &o, NULL, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "proportions 3: neither the body's nor canonical"));
    assert_null(ix);
    /* a segment of length 0 in every template has no direction to keep */
    static float flat[N][3 * L];
    memcpy(flat, s->lm, sizeof flat);
    const int elbow = mim_landmarks_find(&s->map, "l_elbow"), shoulder = mim_landmarks_find(&s->map, "l_shoulder");
    for (uint32_t t = 0; t < N; t++) memcpy(flat[t] + 3 * elbow, flat[t] + 3 * shoulder, 12);
    in.landmarks = &flat[0][0];
    mim_error_clear(&err);
    assert_int_equal(mim_index_build(&ix, &in, NULL, NULL, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "coincide in every template"));
    assert_null(ix);
    mim_landmark_map_t m = s->map;
    snprintf(m.names[head], sizeof m.names[head], "crown");
    assert_int_equal(mim_index_skeleton(&m, parent), MIM_EUNSUPPORTED);
    m = s->map;
    m.count = 15;
    assert_int_equal(mim_index_skeleton(&m, parent), MIM_EUNSUPPORTED);
    free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_other_proportions),
        cmocka_unit_test(test_completion_scale),
        cmocka_unit_test(test_blob),
        cmocka_unit_test(test_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
