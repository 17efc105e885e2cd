/* mimic pairs (issue 14): pose-pairs from two BVH files of one take (root
 * translation kept, joints by name, unit guessed), and coverage (eq. 13)
 * end to end through the binary. The BVH files are written here with every
 * rotation zero, so each joint sits at its rest place plus the root's
 * translation: the test knows every position. */
#include "mim_sample.h"

#include "test_support.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FRAMES 10
#define UNIT (0.0254 / 0.45) /* CMU's: a person ~30 units tall is taken for it */

/* A CMU-named chain: joint, parent, offset (units). Person height ~30 units. */
static const struct { const char *name; int parent; double off[3]; } skel[] = {
    {"Hips", -1, {0, 0, 0}},          {"LeftUpLeg", 0, {1.5, -1, 0}},   {"LeftLeg", 1, {0, -7.5, 0}},
    {"LeftFoot", 2, {0, -7.5, 0}},    {"RightUpLeg", 0, {-1.5, -1, 0}}, {"RightLeg", 4, {0, -7.5, 0}},
    {"RightFoot", 5, {0, -7.5, 0}},   {"Spine", 0, {0, 2, 0}},          {"Spine1", 7, {0, 3, 0}},
    {"Neck", 8, {0, 3, 0}},           {"Head", 9, {0, 1.5, 0}},         {"LeftArm", 8, {3, 2.5, 0}},
    {"LeftForeArm", 11, {5, 0, 0}},   {"LeftHand", 12, {4.5, 0, 0}},    {"RightArm", 8, {-3, 2.5, 0}},
    {"RightForeArm", 14, {-5, 0, 0}}, {"RightHand", 15, {-4.5, 0, 0}},
};
#define NJ ((int)(sizeof skel / sizeof *skel))
/* skel index of each of mimic's 17 joints */
static const int ours[MIM_PAIR_PERSON_JOINTS] = {10, 8, 0, 11, 14, 12, 15, 13, 16, 1, 4, 2, 5, 3, 6, 7, 9};

static char *dir;

static void rest(int j, double p[3])
{
    p[0] = p[1] = p[2] = 0;
    for (int k = j; k >= 0; k = skel[k].parent)
        for (int c = 0; c < 3; c++) p[c] += skel[k].off[c];
}

static double root_x(int person, int f) { return person ? 12.0 - 0.2 * f : 0.3 * f; }

static void block(FILE *fp, int j, int depth)
{
    for (int i = 0; i < depth; i++) fputc('\t', fp);
    fprintf(fp, "%s %s\n", j ? "JOINT" : "ROOT", skel[j].name);
    for (int i = 0; i < depth; i++) fputc('\t', fp);
    fprintf(fp, "{\nOFFSET %g %g %g\n", skel[j].off[0], skel[j].off[1], skel[j].off[2]);
    fprintf(fp, j ? "CHANNELS 3 Zrotation Yrotation Xrotation\n"
                  : "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\n");
    int kids = 0;
    for (int k = 0; k < NJ; k++)
        if (skel[k].parent == j) block(fp, k, depth + 1), kids++;
    if (!kids) fprintf(fp, "End Site\n{\nOFFSET 0 0 1\n}\n");
    fprintf(fp, "}\n");
}

/* person 0 or 1; frames; frame time */
static char *write_bvh(const char *name, int person, int frames, double ft)
{
    char *path = ts_path(dir, name);
    FILE *fp = fopen(path, "w");
    assert_non_null(fp);
    fprintf(fp, "HIERARCHY\n");
    block(fp, 0, 0);
    fprintf(fp, "MOTION\nFrames: %d\nFrame Time: %g\n", frames, ft);
    for (int f = 0; f < frames; f++) {
        fprintf(fp, "%g %g %g", root_x(person, f), 16.0, person ? 3.0 : 0.0);
        for (int k = 0; k < 3 + 3 * (NJ - 1); k++) fprintf(fp, " 0");
        fprintf(fp, "\n");
    }
    fclose(fp);
    return path;
}

/* The true pose-pair of frame f, metres. */
static void truth(int f, double *out)
{
    for (int p = 0; p < 2; p++)
        for (int j = 0; j < MIM_PAIR_PERSON_JOINTS; j++) {
            double r[3];
            rest(ours[j], r);
            double t[3] = {root_x(p, f), 16.0, p ? 3.0 : 0.0};
            for (int c = 0; c < 3; c++) out[3 * (p * MIM_PAIR_PERSON_JOINTS + j) + c] = (r[c] + t[c]) * UNIT;
        }
}

static char *write_samples(const char *name, int from, int to)
{
    char *path = ts_path(dir, name), *h = mim_pairs_jsonl_header();
    FILE *fp = fopen(path, "w");
    fprintf(fp, "%s\n", h);
    free(h);
    for (int f = from; f < to; f++) {
        double p[3 * MIM_PAIR_JOINTS];
        truth(f, p);
        /* a sample lives in its own frame: turn and move it */
        for (int i = 0; i < MIM_PAIR_JOINTS; i++) {
            double x = p[3 * i], z = p[3 * i + 2];
            p[3 * i] = 0.6 * x - 0.8 * z + 5, p[3 * i + 2] = 0.8 * x + 0.6 * z - 2;
        }
        char *l = mim_pairs_jsonl_line(p, -1.0);
        fprintf(fp, "%s\n", l);
        free(l);
    }
    fclose(fp);
    return path;
}

static json_t *coverage_json(const char *const *args)
{
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    if (rc) fail_msg("mimic pairs coverage: exit %d: %s", rc, e);
    json_error_t je;
    json_t *j = json_loads(o, 0, &je);
    if (!j) fail_msg("not JSON: %s", o);
    free(o), free(e);
    return j;
}

static double num(json_t *j, const char *k) { return json_real_value(json_object_get(j, k)); }

static void test_coverage_cli(void **s)
{
    (void)s;
    char *a = write_bvh("a.bvh", 0, FRAMES, 1.0 / 120), *b = write_bvh("b.bvh", 1, FRAMES, 1.0 / 120);
    char spec[8192];
    snprintf(spec, sizeof spec, "%s,%s", a, b);
    char *all = write_samples("all.jsonl", 0, FRAMES), *half = write_samples("half.jsonl", 0, FRAMES / 2),
         *one = write_samples("one.jsonl", 0, 1);
    /* every true frame among the samples (turned and moved): 0 in all three */
    const char *a1[] = {"pairs", "coverage", "--truth", spec, "--samples", all, "--json", NULL};
    json_t *j = coverage_json(a1);
    assert_int_equal(json_integer_value(json_object_get(j, "truth")), FRAMES);
    assert_int_equal(json_integer_value(json_object_get(j, "samples")), FRAMES);
    assert_true(num(j, "D_I") < 1e-6 && num(j, "D_C") < 1e-6 && num(j, "D_S") < 1e-6);
    json_decref(j);
    /* every 2nd from frame 1: 5 true frames */
    const char *a2[] = {"pairs", "coverage", "--truth", spec, "--every", "2", "--offset", "1", "--samples", all, "--json", NULL};
    j = coverage_json(a2);
    assert_int_equal(json_integer_value(json_object_get(j, "truth")), FRAMES / 2);
    json_decref(j);
    /* fewer samples cover less, one sample least; the people move apart, so the distances grow */
    const char *a3[] = {"pairs", "coverage", "--truth", spec, "--samples", half, "--json", NULL};
    const char *a4[] = {"pairs", "coverage", "--truth", spec, "--samples", one, "--json", NULL};
    json_t *jh = coverage_json(a3), *j1 = coverage_json(a4);
    const char *m[3] = {"D_I", "D_C", "D_S"};
    for (int k = 0; k < 3; k++) {
        assert_true(num(jh, m[k]) > 1e-6);
        assert_true(num(j1, m[k]) > num(jh, m[k]));
    }
    json_decref(jh), json_decref(j1);
    /* the human line */
    char *o = NULL, *e = NULL;
    const char *a5[] = {"pairs", "coverage", "--truth", spec, "--samples", all, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, a5), 0);
    assert_non_null(strstr(o, "coverage of 10 true pose-pairs by 10 samples"));
    free(o), free(e), free(a), free(b), free(all), free(half), free(one);
}

/* export writes the take's pose-pairs in the samples format, exactly the
 * true positions in metres, and coverage of the take by them is 0. */
static void test_export(void **s)
{
    (void)s;
    char *a = write_bvh("ea.bvh", 0, FRAMES, 1.0 / 120), *b = write_bvh("eb.bvh", 1, FRAMES, 1.0 / 120);
    char spec[8192], *outp = ts_path(dir, "export.jsonl");
    snprintf(spec, sizeof spec, "%s,%s", a, b);
    const char *args[] = {"pairs", "export", "--pair", spec, "--every", "3", "--offset", "1", "-o", outp, NULL};
    char *o = NULL, *e = NULL;
    assert_int_equal(ts_run_mimic(&o, &e, args), 0);
    assert_non_null(strstr(e, "3 pose-pairs to"));
    free(o), free(e);
    size_t len;
    char *text = ts_read_file(outp, &len);
    mim_pairs_samples_t smp;
    mim_error_t err = {0};
    assert_int_equal(mim_pairs_samples_parse(text, len, outp, &smp, &err), 0);
    assert_int_equal(smp.n, 3); /* frames 1, 4, 7 */
    for (uint32_t k = 0; k < smp.n; k++) {
        double want[3 * MIM_PAIR_JOINTS];
        truth(1 + 3 * (int)k, want);
        for (int i = 0; i < 3 * MIM_PAIR_JOINTS; i++) assert_true(fabs(smp.joints[(size_t)k * 3 * MIM_PAIR_JOINTS + i] - want[i]) < 1e-6);
        assert_true(isnan(smp.log_density[k]));
    }
    mim_pairs_samples_free(&smp);
    free(text);
    const char *cov[] = {"pairs", "coverage", "--truth", spec, "--every", "3", "--offset", "1", "--samples", outp, "--json", NULL};
    json_t *j = coverage_json(cov);
    assert_true(num(j, "D_I") < 1e-6 && num(j, "D_C") < 1e-6 && num(j, "D_S") < 1e-6);
    json_decref(j);
    /* a failed export leaves an existing file as it was */
    char bad_spec[8192];
    snprintf(bad_spec, sizeof bad_spec, "%s,%s", a, "/nonexistent/b.bvh");
    const char *bad[] = {"pairs", "export", "--pair", bad_spec, "-o", outp, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, bad), 1);
    assert_non_null(strstr(e, "/nonexistent/b.bvh"));
    free(o), free(e);
    char *after = ts_read_file(outp, NULL);
    assert_non_null(after);
    assert_int_equal(strlen(after), len);
    free(after), free(a), free(b), free(outp);
}

static void expect_fail(const char *const *args, int code, const char *phrase)
{
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    if (rc != code || !strstr(e, phrase) || strchr(e, '\n') != e + strlen(e) - 1)
        fail_msg("exit %d (wanted %d), stderr '%s' (wanted one line with '%s')", rc, code, e, phrase);
    free(o), free(e);
}

static void test_bad_input(void **s)
{
    (void)s;
    char *a = write_bvh("ba.bvh", 0, FRAMES, 1.0 / 120), *short_b = write_bvh("short.bvh", 1, FRAMES - 1, 1.0 / 120),
         *slow_b = write_bvh("slow.bvh", 1, FRAMES, 1.0 / 60), *b = write_bvh("bb.bvh", 1, FRAMES, 1.0 / 120);
    char *smp = write_samples("s.jsonl", 0, 2), spec[8192];
    snprintf(spec, sizeof spec, "%s,%s", a, short_b);
    const char *c1[] = {"pairs", "coverage", "--truth", spec, "--samples", smp, NULL};
    expect_fail(c1, 1, "10 and 9 frames");
    snprintf(spec, sizeof spec, "%s,%s", a, slow_b);
    expect_fail(c1, 1, "one take has one rate");
    /* joints of no scheme: renamed hands */
    char *text = ts_read_file(a, NULL), *p;
    while ((p = strstr(text, "LeftHand"))) memcpy(p, "LeftPalm", 8);
    char *renamed = ts_path(dir, "renamed.bvh");
    ts_write_file(renamed, text, strlen(text));
    free(text);
    snprintf(spec, sizeof spec, "%s,%s", renamed, b);
    expect_fail(c1, 1, "no LeftHand joint (l_wrist); give --joint-map");
    /* ... which a joint map fixes */
    char *map = ts_path(dir, "map.json"), mtext[2048] = "{";
    static const char *const cmu[MIM_PAIR_PERSON_JOINTS] = {"Head", "Spine1", "Hips", "LeftArm", "RightArm", "LeftForeArm",
                                                            "RightForeArm", "LeftPalm", "RightHand", "LeftUpLeg", "RightUpLeg",
                                                            "LeftLeg", "RightLeg", "LeftFoot", "RightFoot", "Spine", "Neck"};
    for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++)
        snprintf(mtext + strlen(mtext), sizeof mtext - strlen(mtext), "%s\"%s\": \"%s\"", k ? ", " : "",
                 mim_sample_joint_names[k], cmu[k]);
    strcat(mtext, "}");
    ts_write_file(map, mtext, strlen(mtext));
    char renamed_b[8192];
    snprintf(renamed_b, sizeof renamed_b, "%s,%s", renamed, renamed);
    const char *c2[] = {"pairs", "coverage", "--truth", renamed_b, "--joint-map", map, "--samples", smp, NULL};
    char *o = NULL, *e = NULL;
    assert_int_equal(ts_run_mimic(&o, &e, c2), 0);
    free(o), free(e);
    /* a bad samples file names its line */
    char *bad = ts_path(dir, "bad.jsonl"), *h = mim_pairs_jsonl_header(), btext[4096];
    snprintf(btext, sizeof btext, "%s\n{\"joints\": [[1, 2, 3]]}\n", h);
    ts_write_file(bad, btext, strlen(btext));
    snprintf(spec, sizeof spec, "%s,%s", a, b);
    const char *c3[] = {"pairs", "coverage", "--truth", spec, "--samples", bad, NULL};
    expect_fail(c3, 1, "bad.jsonl:2: \"joints\" must hold 34");
    /* usage */
    const char *c4[] = {"pairs", "coverage", "--truth", spec, NULL};
    expect_fail(c4, 2, "--samples FILE are required");
    const char *c5[] = {"pairs", "coverage", "--truth", a, "--samples", smp, NULL};
    expect_fail(c5, 1, "give two motion files of one take");
    const char *c6[] = {"pairs", "frobnicate", NULL};
    expect_fail(c6, 2, "unknown subcommand 'frobnicate'");
    const char *c7[] = {"pairs", "coverage", "--truth", spec, "--samples", smp, "--unit", "-1", NULL};
    expect_fail(c7, 2, "--unit '-1'");
    /* a unit that cannot be guessed: a person 300 units tall */
    (void)c7;
    free(a), free(short_b), free(slow_b), free(b), free(smp), free(renamed), free(map), free(bad), free(h);
}

static int setup(void **s)
{
    (void)s;
    dir = ts_tempdir("pairs");
    return dir ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_coverage_cli), cmocka_unit_test(test_export),
                                       cmocka_unit_test(test_bad_input)};
    return cmocka_run_group_tests(tests, setup, NULL);
}
