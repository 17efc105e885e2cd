/* mimic pairs (issue 14): pose-pairs from two BVH files of one take (root
 * translation kept, joints by name, unit guessed), and coverage (eq. 13)
 * end to end through the binary. The BVH files are written here with every
 * rotation zero, so each joint sits at its rest place plus the root's
 * translation: the test knows every position. */
#include "mim_sample.h"
#include "mim_sample_mcmc.h"

#include "cmu_skeleton.h"
#include "test_support.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define FRAMES 10
#define UNIT (0.0254 / 0.45) /* CMU's: a person ~30 units tall is taken for it */

/* skel index of each of mimic's 17 joints */
static const int ours[MIM_PAIR_PERSON_JOINTS] = {10, 8, 0, 11, 14, 12, 15, 13, 16, 1, 4, 2, 5, 3, 6, 7, 9};

static char *dir;

static void rest(int j, double p[3])
{
    p[0] = p[1] = p[2] = 0;
    for (int k = j; k >= 0; k = cmu_skel[k].parent)
        for (int c = 0; c < 3; c++) p[c] += cmu_skel[k].off[c];
}

static double root_x(int person, int f) { return person ? 12.0 - 0.2 * f : 0.3 * f; }

/* write_bvh_scaled's scale of the skeleton and shift of person B's root (units) */
static double g_scale = 1.0, g_shift = 0.0;

static void block(FILE *fp, int j, int depth)
{
    for (int i = 0; i < depth; i++) fputc('\t', fp);
    fprintf(fp, "%s %s\n", j ? "JOINT" : "ROOT", cmu_skel[j].name);
    for (int i = 0; i < depth; i++) fputc('\t', fp);
    fprintf(fp, "{\nOFFSET %g %g %g\n", g_scale * cmu_skel[j].off[0], g_scale * cmu_skel[j].off[1], g_scale * cmu_skel[j].off[2]);
    fprintf(fp, j ? "CHANNELS 3 Zrotation Yrotation Xrotation\n"
                  : "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\n");
    int kids = 0;
    for (int k = 0; k < CMU_SKEL_JOINTS; k++)
        if (cmu_skel[k].parent == j) block(fp, k, depth + 1), kids++;
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
        fprintf(fp, "%g %g %g", root_x(person, f) + (person ? g_shift : 0.0), 16.0, person ? 3.0 : 0.0);
        for (int k = 0; k < 3 + 3 * (CMU_SKEL_JOINTS - 1); k++) fprintf(fp, " 0");
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
    /* the same figures on one thread as on several (the output is exact) */
    const char *a6[] = {"pairs", "coverage", "--truth", spec, "--samples", half, "--threads", "1", NULL};
    const char *a7[] = {"pairs", "coverage", "--truth", spec, "--samples", half, "--threads", "3", NULL};
    char *o1 = NULL, *o3 = NULL, *e1 = NULL, *e3 = NULL;
    assert_int_equal(ts_run_mimic(&o1, &e1, a6), 0);
    assert_int_equal(ts_run_mimic(&o3, &e3, a7), 0);
    assert_string_equal(o1, o3);
    free(o1), free(o3), free(e1), free(e3);
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

/* annotate: every N-th frame through V cameras; with no noise each point
 * is its joint through the camera written to --cameras; with noise the
 * deviations have the spread asked for; one seed, one output. */
static void test_annotate(void **s)
{
    (void)s;
    char *a = write_bvh("na.bvh", 0, FRAMES, 1.0 / 120), *b = write_bvh("nb.bvh", 1, FRAMES, 1.0 / 120);
    char spec[8192], *ann = ts_path(dir, "ann.json"), *cams = ts_path(dir, "cams.json"), *ann2 = ts_path(dir, "ann2.json");
    snprintf(spec, sizeof spec, "%s,%s", a, b);
    const char *a0[] = {"pairs", "annotate", "--pair", spec, "--every", "3", "--offset", "1", "--views", "3",
                        "--noise-px", "0", "-o", ann, "--cameras", cams, NULL};
    char *o = NULL, *e = NULL;
    assert_int_equal(ts_run_mimic(&o, &e, a0), 0);
    assert_non_null(strstr(e, "9 annotations (3 views of 3 frames)"));
    free(o), free(e);
    size_t len;
    char *text = ts_read_file(ann, &len);
    mim_pairs_annotations_t an;
    mim_error_t err = {0};
    assert_int_equal(mim_pairs_annotations_parse(text, len, ann, &an, &err), 0);
    free(text);
    assert_int_equal(an.n, 9);
    assert_int_equal(an.width, 1920);
    json_error_t je;
    json_t *cj = json_load_file(cams, 0, &je), *cl = json_object_get(cj, "cameras");
    assert_int_equal(json_array_size(cl), 9);
    for (uint32_t i = 0; i < an.n; i++) {
        assert_int_equal(an.frame[i], 1 + 3 * (i / 3));
        assert_int_equal(an.view[i], i % 3);
        json_t *c = json_array_get(cl, i);
        mim_pairs_camera_t cam = {.width = 1920, .height = 1080};
        for (int k = 0; k < 3; k++) cam.position[k] = json_real_value(json_array_get(json_object_get(c, "position"), (size_t)k));
        for (int k = 0; k < 9; k++) cam.R[k] = json_real_value(json_array_get(json_object_get(c, "rotation"), (size_t)k));
        cam.focal_px = json_real_value(json_object_get(c, "focal_px"));
        cam.cx = json_real_value(json_array_get(json_object_get(c, "center"), 0));
        cam.cy = json_real_value(json_array_get(json_object_get(c, "center"), 1));
        double joints[3 * MIM_PAIR_JOINTS], uv[2 * MIM_PAIR_JOINTS];
        truth((int)an.frame[i], joints);
        assert_int_equal(mim_pairs_project(&cam, joints, uv), 1); /* whole pair in view */
        for (int k = 0; k < 2 * MIM_PAIR_JOINTS; k++)
            if (fabs(uv[k] - an.points[(size_t)i * 2 * MIM_PAIR_JOINTS + k]) > 1e-3)
                fail_msg("annotation %u, coordinate %d: %g, the camera gives %g", i, k,
                         an.points[(size_t)i * 2 * MIM_PAIR_JOINTS + k], uv[k]);
        /* the views of one frame are different cameras */
        if (i % 3) assert_true(fabs(an.points[(size_t)i * 2 * MIM_PAIR_JOINTS] - an.points[(size_t)(i - 1) * 2 * MIM_PAIR_JOINTS]) > 1.0);
    }
    json_decref(cj);
    /* noise of 3 px: the spread of the deviations from the noiseless points */
    const char *a1[] = {"pairs", "annotate", "--pair", spec, "--every", "3", "--offset", "1", "--views", "3",
                        "--noise-px", "3", "-o", ann2, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, a1), 0);
    free(o), free(e);
    text = ts_read_file(ann2, &len);
    mim_pairs_annotations_t noisy;
    assert_int_equal(mim_pairs_annotations_parse(text, len, ann2, &noisy, &err), 0);
    free(text);
    double ss = 0;
    size_t cnt = (size_t)an.n * 2 * MIM_PAIR_JOINTS;
    for (size_t k = 0; k < cnt; k++) ss += (noisy.points[k] - an.points[k]) * (noisy.points[k] - an.points[k]);
    double sd = sqrt(ss / cnt);
    print_message("noise: %.2f px measured for 3 px asked (%zu coordinates)\n", sd, cnt);
    assert_true(sd > 2.6 && sd < 3.4);
    mim_pairs_annotations_free(&noisy);
    mim_pairs_annotations_free(&an);
    /* the same seed, the same bytes; another seed, other cameras */
    char *ann3 = ts_path(dir, "ann3.json"), *ann4 = ts_path(dir, "ann4.json");
    const char *a2[] = {"pairs", "annotate", "--pair", spec, "--seed", "9", "-o", ann3, NULL};
    const char *a3[] = {"pairs", "annotate", "--pair", spec, "--seed", "9", "-o", ann4, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, a2), 0), free(o), free(e);
    assert_int_equal(ts_run_mimic(&o, &e, a3), 0), free(o), free(e);
    char *t3 = ts_read_file(ann3, NULL), *t4 = ts_read_file(ann4, NULL);
    assert_string_equal(t3, t4);
    const char *a4[] = {"pairs", "annotate", "--pair", spec, "--seed", "10", "-o", ann4, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, a4), 0), free(o), free(e);
    free(t4);
    t4 = ts_read_file(ann4, NULL);
    assert_string_not_equal(t3, t4);
    free(t3), free(t4), free(ann3), free(ann4), free(a), free(b), free(ann), free(cams), free(ann2);
}

/* The annotations reader refuses what is not annotations, in one line. */
static void test_annotations_reader(void **s)
{
    (void)s;
    mim_pairs_annotations_t a = {0};
    mim_error_t err = {0};
    uint32_t take = 0, frame = 4, view = 1, shot = 7;
    double pts[2 * MIM_PAIR_JOINTS];
    for (int k = 0; k < 2 * MIM_PAIR_JOINTS; k++) pts[k] = 100 + k;
    mim_pairs_annotations_t one = {1, 640, 480, &take, &frame, &view, &shot, pts};
    const char *takes[] = {"a.bvh,b.bvh"};
    char *good = mim_pairs_annotations_json(&one, takes, 1);
    assert_non_null(good);
    assert_int_equal(mim_pairs_annotations_parse(good, strlen(good), "ann.json", &a, &err), 0);
    assert_int_equal(a.n, 1), assert_int_equal(a.width, 640), assert_int_equal(a.frame[0], 4);
    assert_int_equal(a.shot[0], 7);
    for (int k = 0; k < 2 * MIM_PAIR_JOINTS; k++) assert_true(fabs(a.points[k] - pts[k]) < 1e-4);
    mim_pairs_annotations_free(&a);
    struct { const char *from, *to; int code; const char *phrase; } bad[] = {
        {"mimic pair annotations 1", "something", MIM_EFORMAT, "not mimic pair annotations"},
        {"\"A.head\"", "\"A.nose\"", MIM_EFORMAT, "must name the 34 joints"},
        {"[640,480]", "[640]", MIM_EFORMAT, "\"image\" must be [width, height]"},
        {"\"frame\":4", "\"frame\":-4", MIM_EFORMAT, "annotation 0: \"take\" (an index into \"takes\")"},
        {"\"take\":0", "\"take\":1", MIM_EFORMAT, "annotation 0: \"take\" (an index into \"takes\")"}, /* one take */
        {"\"takes\":[\"a.bvh,b.bvh\"]", "\"takes\":[]", MIM_EFORMAT, "\"takes\" must list"},
        {"[100.0,101.0]", "[100.0]", MIM_EFORMAT, "annotation 0: joint 0 is not [u, v]"},
        {"[100.0,101.0]", "[1e300,101.0]", MIM_ENONFINITE, "joint 0: 1e+300 is not a pixel coordinate"},
        {"\"annotations\":[", "\"annotations\":[],\"x\":[", MIM_EEMPTY, "ann.json: no annotations"},
        {"\"shot\":7", "\"shot\":-7", MIM_EFORMAT, "annotation 0: \"shot\" must be a whole number"},
        {"\"shot\":7", "\"shot\":\"7\"", MIM_EFORMAT, "annotation 0: \"shot\" must be a whole number"},
    };
    for (size_t k = 0; k < sizeof bad / sizeof *bad; k++) {
        char *p = strstr(good, bad[k].from);
        if (!p) fail_msg("case %zu: '%s' not in %s", k, bad[k].from, good);
        char buf[16384];
        snprintf(buf, sizeof buf, "%.*s%s%s", (int)(p - good), good, bad[k].to, p + strlen(bad[k].from));
        mim_error_clear(&err);
        int rc = mim_pairs_annotations_parse(buf, strlen(buf), "ann.json", &a, &err);
        if (rc != bad[k].code || !strstr(err.msg, bad[k].phrase))
            fail_msg("case %zu: %d '%s' (wanted %d '%s')", k, rc, err.msg, bad[k].code, bad[k].phrase);
        assert_int_equal(a.n, 0);
    }
    /* a photo: no "shot" */
    char *p = strstr(good, "\"shot\":7,");
    assert_non_null(p);
    memmove(p, p + strlen("\"shot\":7,"), strlen(p + strlen("\"shot\":7,")) + 1);
    assert_int_equal(mim_pairs_annotations_parse(good, strlen(good), "ann.json", &a, &err), 0);
    assert_int_equal(a.shot[0], MIM_PAIRS_NO_SHOT);
    mim_pairs_annotations_free(&a);
    /* a take named by bytes that are not UTF-8: no file rather than a short "takes" */
    const char *bad_takes[] = {"a\xff.bvh,b.bvh"};
    assert_null(mim_pairs_annotations_json(&one, bad_takes, 1));
    mim_error_clear(&err);
    assert_int_equal(mim_pairs_annotations_parse("{\"format\": ", 12, "ann.json", &a, &err), MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "ann.json:1:"));
    free(good);
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
    const char *c7t[] = {"pairs", "coverage", "--truth", spec, "--samples", smp, "--threads", "0", NULL};
    expect_fail(c7t, 2, "--threads '0'");
    /* a unit that cannot be guessed: people ten times CMU's size (about
     * 300 units tall), unless --unit gives it */
    g_scale = 10.0;
    char *ta = write_bvh("tall_a.bvh", 0, FRAMES, 1.0 / 120), *tb = write_bvh("tall_b.bvh", 1, FRAMES, 1.0 / 120);
    g_scale = 1.0;
    char tall[8192];
    snprintf(tall, sizeof tall, "%s,%s", ta, tb);
    const char *c8[] = {"pairs", "coverage", "--truth", tall, "--samples", smp, NULL};
    expect_fail(c8, 1, "tall_a.bvh: cannot tell the unit: the person spans 255 units from head to ankles; give --unit");
    const char *c9[] = {"pairs", "coverage", "--truth", tall, "--samples", smp, "--unit", "0.005", NULL};
    assert_int_equal(ts_run_mimic(&o, &e, c9), 0);
    free(o), free(e);
    /* people 100 m apart: no camera of annotate sees both */
    g_shift = 1800.0;
    char *fb = write_bvh("far_b.bvh", 1, FRAMES, 1.0 / 120);
    g_shift = 0.0;
    char far[8192];
    snprintf(far, sizeof far, "%s,%s", a, fb);
    char *ann = ts_path(dir, "far.json");
    const char *c10[] = {"pairs", "annotate", "--pair", far, "-o", ann, NULL};
    char *want_far = NULL;
    assert_true(asprintf(&want_far, "%s: frame 0: no camera sees both people whole", far) > 0);
    char *o2 = NULL, *e2 = NULL;
    assert_int_equal(ts_run_mimic(&o2, &e2, c10), 1);
    if (!strstr(e2, want_far)) fail_msg("far apart: %s", e2);
    assert_int_equal(access(ann, F_OK), -1); /* nothing written */
    free(o2), free(e2), free(want_far), free(ann), free(fb), free(ta), free(tb);
    free(a), free(short_b), free(slow_b), free(b), free(smp), free(renamed), free(map), free(bad), free(h);
}

/* pairs sample end to end: a report as schemas/pairs-sample says, samples
 * whose bones are the annotated take's as its annotations show them (the
 * chains keep a lifted seed's bones), the same bytes from the same seed, BVH
 * files, the prior density without annotations, and bad input refused
 * with nothing written. */
static void test_sample_cli(void **s)
{
    (void)s;
    char *a = write_bvh("sa.bvh", 0, FRAMES, 1.0 / 120), *b = write_bvh("sb.bvh", 1, FRAMES, 1.0 / 120);
    char spec[8192], *ann = ts_path(dir, "video.json"), *s1 = ts_path(dir, "s1.jsonl"), *s2 = ts_path(dir, "s2.jsonl"),
                     *s3 = ts_path(dir, "s3.jsonl"), *bvh = ts_path(dir, "bvh");
    snprintf(spec, sizeof spec, "%s,%s", a, b);
    const char *an[] = {"pairs", "annotate", "--pair", spec, "--every", "1", "--views", "3", "--video", "-o", ann, NULL};
    char *o = NULL, *e = NULL;
    assert_int_equal(ts_run_mimic(&o, &e, an), 0);
    free(o), free(e);
    size_t len;
    char *text = ts_read_file(ann, &len);
    mim_pairs_annotations_t av;
    mim_error_t err = {0};
    assert_int_equal(mim_pairs_annotations_parse(text, len, ann, &av, &err), 0);
    for (uint32_t i = 0; i < av.n; i++) assert_int_equal(av.shot[i], av.view[i]); /* one video a camera: it keeps them */
    /* the bones the lifting takes: the take's, from its annotations, in the prior's metres (how near
     * the true lengths: test_sampler's test_lengths_2d) */
    double *frames = malloc((size_t)FRAMES * 3 * MIM_PAIR_JOINTS * sizeof *frames), prior_len[MIM_PAIR_PERSON_JOINTS],
           take_len[MIM_PAIR_PERSON_JOINTS];
    for (int f = 0; f < FRAMES; f++) truth(f, frames + (size_t)f * 3 * MIM_PAIR_JOINTS);
    mim_pairs_bone_lengths(frames, FRAMES, prior_len);
    mim_pairs_bone_lengths_2d(&av, 0, prior_len, take_len);
    free(frames);
    mim_pairs_annotations_free(&av);
    free(text);
    const char *run1[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "60", "--chains", "2",
                          "--seed", "5", "--json", "--bvh", bvh, "-o", s1, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, run1), 0);
    json_error_t je;
    json_t *rep = json_loads(o, 0, &je);
    if (!rep) fail_msg("not JSON: %s", o);
    assert_int_equal(json_integer_value(json_object_get(rep, "samples")), 60);
    assert_int_equal(json_array_size(json_object_get(rep, "acceptance")), 2);
    assert_true(num(rep, "samples_per_second") > 0);
    assert_string_equal(json_string_value(json_object_get(json_object_get(rep, "parameters"), "density")), "ic");
    assert_int_equal(json_integer_value(json_object_get(rep, "annotations")), 3 * FRAMES);
    double acc = 0;
    for (int c = 0; c < 2; c++) acc += json_real_value(json_array_get(json_object_get(rep, "acceptance"), c));
    assert_true(acc > 0);
    json_decref(rep);
    free(o), free(e);
    /* the samples: 60, bones as long as the take's, not all one pose */
    text = ts_read_file(s1, &len);
    mim_pairs_samples_t sm;
    assert_int_equal(mim_pairs_samples_parse(text, len, s1, &sm, &err), 0);
    free(text);
    assert_int_equal(sm.n, 60);
    double spread = 0;
    for (uint32_t i = 0; i < sm.n; i++) {
        const double *x = sm.joints + (size_t)i * 3 * MIM_PAIR_JOINTS;
        assert_true(isfinite(sm.log_density[i]));
        /* head to neck and knee to ankle, each person */
        static const int bone[2][2] = {{0, 16}, {11, 13}};
        for (int p = 0; p < 2; p++)
            for (int k = 0; k < 2; k++) {
                int u = p * MIM_PAIR_PERSON_JOINTS + bone[k][0], v = p * MIM_PAIR_PERSON_JOINTS + bone[k][1];
                double d = 0;
                for (int c = 0; c < 3; c++) d += (x[3 * u + c] - x[3 * v + c]) * (x[3 * u + c] - x[3 * v + c]);
                assert_true(fabs(sqrt(d) - take_len[k ? bone[k][1] : bone[k][0]]) < 1e-5);
            }
        for (int c = 0; c < 3; c++) spread = fmax(spread, fabs(x[3 * 7 + c] - sm.joints[3 * 7 + c])); /* A's left wrist */
    }
    assert_true(spread > 0.005);
    mim_pairs_samples_free(&sm);
    /* BVH: a pair per chain */
    for (int c = 0; c < 2; c++)
        for (int p = 0; p < 2; p++) {
            char name[64];
            snprintf(name, sizeof name, "bvh/chain%d_%c.bvh", c, p ? 'B' : 'A');
            char *path = ts_path(dir, name), *t = ts_read_file(path, NULL);
            assert_non_null(t);
            assert_memory_equal(t, "HIERARCHY", 9);
            assert_non_null(strstr(t, "Frames: 30"));
            free(t), free(path);
        }
    /* the same seed, the same bytes; another seed, others */
    const char *run2[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "60", "--chains", "2",
                          "--seed", "5", "-o", s2, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, run2), 0);
    free(o), free(e);
    char *t1 = ts_read_file(s1, NULL), *t2 = ts_read_file(s2, NULL);
    assert_string_equal(t1, t2);
    free(t2);
    const char *run3[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "60", "--chains", "2",
                          "--seed", "6", "-o", s3, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, run3), 0);
    free(o), free(e);
    t2 = ts_read_file(s3, NULL);
    assert_true(strcmp(t1, t2) != 0);
    free(t1), free(t2);
    /* the prior alone needs no annotations; --start restarts from a sample */
    char start[8192];
    snprintf(start, sizeof start, "%s:7", s1);
    const char *run4[] = {"pairs", "sample", "--prior", spec, "--density", "prior", "--samples", "10", "--chains", "1",
                          "--start", start, "-o", s3, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, run4), 0);
    free(o), free(e);
    /* --seed-jitter edits the seed (the same way for the same seed): the
     * first sample moves away from the unedited run's */
    char *j1 = ts_path(dir, "j1.jsonl"), *j2 = ts_path(dir, "j2.jsonl");
    const char *jit[] = {"pairs", "sample", "--prior", spec, "--density", "prior", "--samples", "10", "--chains", "1",
                         "--start", start, "--seed-jitter", "5,0.05", "-o", j1, "--json", NULL};
    if (ts_run_mimic(&o, &e, jit)) fail_msg("%s", e);
    json_error_t jerr;
    json_t *jrep = json_loads(o, 0, &jerr);
    assert_non_null(jrep);
    json_t *params = json_object_get(jrep, "parameters");
    assert_true(fabs(json_real_value(json_object_get(params, "seed_jitter_deg")) - 5) < 1e-9);
    assert_true(fabs(json_real_value(json_object_get(params, "seed_jitter_m")) - 0.05) < 1e-9);
    json_decref(jrep);
    free(o), free(e);
    jit[15] = j2;
    assert_int_equal(ts_run_mimic(&o, &e, jit), 0);
    free(o), free(e);
    char *tj1 = ts_read_file(j1, NULL), *tj2 = ts_read_file(j2, NULL), *tplain = ts_read_file(s3, NULL);
    assert_string_equal(tj1, tj2);
    assert_true(strcmp(tj1, tplain) != 0);
    free(tj1), free(tj2), free(tplain), free(j1), free(j2);
    /* K seeds (--start F:L1,L2): chain k starts from the k-th line, so each
     * chain's samples are those of a run with its line alone */
    char *k1 = ts_path(dir, "k1.jsonl"), *k2 = ts_path(dir, "k2.jsonl"), *k12 = ts_path(dir, "k12.jsonl");
    const char *lines_of[3] = {"7", "12", "7,12"};
    char *outs[3] = {k1, k2, k12};
    for (int r = 0; r < 3; r++) {
        snprintf(start, sizeof start, "%s:%s", s1, lines_of[r]);
        const char *run5[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "10", "--chains", "2",
                              "--restart-every", "0", "--start", start, "-o", outs[r], NULL};
        assert_int_equal(ts_run_mimic(&o, &e, run5), 0);
        free(o), free(e);
    }
    char *body[3];
    for (int r = 0; r < 3; r++) {
        char *t = ts_read_file(outs[r], NULL);
        body[r] = strdup(strchr(t, '\n') + 1); /* after the header: chain 0's 5 lines, then chain 1's */
        free(t);
    }
    char *c0[3], *c1[3];
    for (int r = 0; r < 3; r++) {
        char *p = body[r];
        for (int l = 0; l < 5; l++) p = strchr(p, '\n') + 1;
        c1[r] = strdup(p), *p = 0, c0[r] = body[r];
    }
    assert_string_equal(c0[2], c0[0]);
    assert_string_equal(c1[2], c1[1]);
    assert_true(strcmp(c0[0], c0[1]) != 0);
    for (int r = 0; r < 3; r++) free(c0[r]), free(c1[r]);
    free(k1), free(k2), free(k12);
    /* bad input: usage (2) and inputs (1), nothing written */
    char *none = ts_path(dir, "none.jsonl"), *junk = ts_path(dir, "junk.json");
    const char *junk_text = "{\"format\": \"mimic pair annotations 1\"";
    ts_write_file(junk, junk_text, strlen(junk_text));
    const char *b1[] = {"pairs", "sample", "--prior", spec, "--samples", "10", "-o", none, NULL};
    expect_fail(b1, 2, "--density ic needs --annotations");
    const char *b2[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "0", "-o", none, NULL};
    expect_fail(b2, 2, "samples");
    const char *b3[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "5", "--density", "nope", "-o", none, NULL};
    expect_fail(b3, 2, "--density 'nope' is not ic, cartesian, shape or prior");
    const char *b4[] = {"pairs", "sample", "--prior", spec, "--annotations", junk, "--samples", "5", "-o", none, NULL};
    expect_fail(b4, 1, "junk.json:1:");
    snprintf(start, sizeof start, "%s:99", s1);
    const char *b5[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "5", "--start", start, "-o", none, NULL};
    expect_fail(b5, 1, "has 60 samples, not 99");
    const char *b6[] = {"pairs", "sample", "--annotations", ann, "--samples", "5", "-o", none, NULL};
    expect_fail(b6, 2, "--prior A,B, --samples N and -o FILE are required");
    const char *b7[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "5", "--velocity-scale", "-1", "-o", none, NULL};
    expect_fail(b7, 2, "--velocity-scale '-1' is not a scale in 0..100");
    const char *b8[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "5", "--restart-every", "x", "-o", none, NULL};
    expect_fail(b8, 2, "--restart-every 'x' is not a number");
    const char *b9[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "5", "--chains", "0", "-o", none, NULL};
    expect_fail(b9, 2, "--chains '0' is not a number in 1..256");
    static const char *const jitters[][2] = {{"15", "--seed-jitter '15' is not DEG,M"},
                                             {"95,0", "does not start with degrees in 0..90"},
                                             {"5,-1", "does not end with metres in 0..10"}};
    for (size_t k = 0; k < sizeof jitters / sizeof jitters[0]; k++) {
        const char *jb[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "5",
                            "--seed-jitter", jitters[k][0], "-o", none, NULL};
        expect_fail(jb, 2, jitters[k][1]);
    }
    snprintf(start, sizeof start, "%s:7", s1);
    const char *j6[] = {"pairs", "sample", "--prior", spec, "--density", "prior", "--samples", "5", "--start", start,
                        "--seed-jitter", "90,5", "-o", none, NULL};
    expect_fail(j6, 1, "a smaller --seed-jitter?");
    snprintf(start, sizeof start, "%s:3", none);
    const char *b10[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "5", "--start", start, "-o", none, NULL};
    expect_fail(b10, 1, "--start: ");
    snprintf(start, sizeof start, "%s:7,,3", s1);
    const char *st11[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "5", "--start", start, "-o", none, NULL};
    expect_fail(st11, 2, "--start's line '' is not a number");
    snprintf(start, sizeof start, "%s:7,61", s1);
    const char *st12[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "5", "--start", start, "-o", none, NULL};
    expect_fail(st12, 1, "has 60 samples, not 61");
    snprintf(start, sizeof start, "%s:1,2,3", s1);
    const char *st13[] = {"pairs", "sample", "--prior", spec, "--annotations", ann, "--samples", "5", "--chains", "2",
                          "--start", start, "-o", none, NULL};
    expect_fail(st13, 2, "--start gives 3 lines for 2 chains");
    /* annotations whose torsos all sit at one pixel: no view can be estimated */
    char *flat = ts_path(dir, "flat.json");
    text = ts_read_file(ann, &len);
    mim_pairs_annotations_t fa;
    assert_int_equal(mim_pairs_annotations_parse(text, len, ann, &fa, &err), 0);
    free(text);
    for (size_t k = 0; k < (size_t)fa.n * 2 * MIM_PAIR_JOINTS; k++) fa.points[k] = 100.0;
    const char *takes[] = {spec};
    char *ft = mim_pairs_annotations_json(&fa, takes, 1);
    ts_write_file(flat, ft, strlen(ft));
    free(ft);
    mim_pairs_annotations_free(&fa);
    const char *b11[] = {"pairs", "sample", "--prior", spec, "--annotations", flat, "--samples", "5", "-o", none, NULL};
    expect_fail(b11, 1, "no annotation has a view that can be estimated");
    assert_int_equal(access(none, F_OK), -1);
    free(a), free(b), free(ann), free(s1), free(s2), free(s3), free(bvh), free(none), free(junk), free(flat);
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
                                       cmocka_unit_test(test_annotate), cmocka_unit_test(test_annotations_reader),
                                       cmocka_unit_test(test_bad_input), cmocka_unit_test(test_sample_cli)};
    return cmocka_run_group_tests(tests, setup, NULL);
}
