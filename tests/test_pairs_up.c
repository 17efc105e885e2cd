/* The up axis of motion files: one two-person take written y up, z up and
 * x up (support/bvh_turn.c turns every offset and channel) gives the same
 * pose-pairs, annotations, samples and coverage through the binary, each
 * command saying which axis it found; --up overrides; a take whose two
 * files disagree, and a bad --up, are refused in one line. The vest's
 * orientation reader (mim_vest_motion_t) likewise finds the axis and turns
 * on request, and the joint reader falls back to the frames when the rest
 * pose does not stand. */
#include "bvh_turn.h"
#include "mim_sample.h"
#include "mim_vest_motion.h"

#include "cmu_skeleton.h"
#include "test_support.h"

#include <jansson.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FRAMES 24


static char *dir;

/* Text growing by printf. */
typedef struct { char *s; size_t n; } text_t;
__attribute__((format(printf, 2, 3))) static void put(text_t *t, const char *fmt, ...)
{
    char line[4096];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    size_t l = strlen(line);
    t->s = realloc(t->s, t->n + l + 1);
    memcpy(t->s + t->n, line, l + 1);
    t->n += l;
}
#define PUT(...) put(b, __VA_ARGS__)

static void block(text_t *b, int j, int depth)
{
    PUT("%*s%s %s\n%*s{\n", depth, "", j ? "JOINT" : "ROOT", cmu_skel[j].name, depth, "");
    PUT("OFFSET %g %g %g\n", cmu_skel[j].off[0], cmu_skel[j].off[1], cmu_skel[j].off[2]);
    PUT(j ? "CHANNELS 3 Zrotation Xrotation Yrotation\n"
          : "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n");
    int kids = 0;
    for (int k = 0; k < CMU_SKEL_JOINTS; k++)
        if (cmu_skel[k].parent == j) block(b, k, depth + 1), kids++;
    if (!kids) PUT("End Site\n{\nOFFSET 0 1 0\n}\n");
    PUT("}\n");
}

/* Person 0 or 1 of a take, y up: arms and legs swing, the torso turns, the
 * people walk; person 1 stands 40 units away facing person 0. */
static char *take_text(int person)
{
    text_t t0 = {0}, *b = &t0;
    PUT("HIERARCHY\n");
    block(b, 0, 0);
    PUT("MOTION\nFrames: %d\nFrame Time: 0.0333333\n", FRAMES);
    for (int f = 0; f < FRAMES; f++) {
        double t = f / (double)FRAMES, s = sin(2 * M_PI * t + person), c = cos(2 * M_PI * t + person);
        double v[6 + 3 * (CMU_SKEL_JOINTS - 1)] = {0};
        v[0] = person ? 3 - 4 * t : 5 * t, v[1] = 16 + 0.5 * s, v[2] = person ? 40 : 0;
        v[3] = 4 * s, v[4] = 6 * c, v[5] = (person ? 180 : 0) + 25 * s; /* root: Z X Y */
        double *j = v + 6 - 3;                                           /* joint k's at j + 3k */
        j[3 * 1 + 1] = -30 * s, j[3 * 2 + 1] = 35 + 30 * c;             /* left hip, knee */
        j[3 * 4 + 1] = 30 * s, j[3 * 5 + 1] = 35 - 30 * c;              /* right */
        j[3 * 8 + 2] = -20 * s, j[3 * 10 + 1] = 12 * c;                 /* chest turns, head nods */
        j[3 * 11 + 0] = -70 + 15 * s, j[3 * 11 + 1] = 40 * s, j[3 * 12 + 2] = 30 + 30 * c; /* left arm */
        j[3 * 14 + 0] = 70 - 15 * s, j[3 * 14 + 1] = -40 * c, j[3 * 15 + 2] = -30 - 30 * s;
        for (size_t i = 0; i < sizeof v / sizeof *v; i++) PUT("%s%.9g", i ? " " : "", v[i]);
        PUT("\n");
    }
    return t0.s;
}

/* The take written with up axis `up` into DIR/NAME_a.bvh, _b.bvh: "A,B" (malloc'd). */
static char *write_take(const char *name, int up_a, int up_b)
{
    char *spec = malloc(8192), *p[2];
    for (int who = 0; who < 2; who++) {
        char file[128];
        snprintf(file, sizeof file, "%s_%c.bvh", name, "ab"[who]);
        char *text = take_text(who), *turned = bt_turn(text, who ? up_b : up_a);
        p[who] = ts_path(dir, file);
        assert_int_equal(ts_write_file(p[who], turned, strlen(turned)), 0);
        free(text), free(turned);
    }
    snprintf(spec, 8192, "%s,%s", p[0], p[1]);
    free(p[0]), free(p[1]);
    return spec;
}

/* Runs mimic; exit status rc expected; stderr to *err (malloc'd) when asked. */
/* Every number in a and b (objects, arrays) within tol; strings ignored
 * (they name the files). Returns how many numbers were compared. */
static size_t same_numbers(json_t *a, json_t *b, double tol)
{
    if (json_is_number(a)) {
        assert_true(json_is_number(b));
        double x = json_number_value(a), y = json_number_value(b);
        if (!(fabs(x - y) <= tol * fmax(1.0, fabs(x)))) fail_msg("%.12g against %.12g", x, y);
        return 1;
    }
    size_t n = 0;
    if (json_is_array(a)) {
        assert_int_equal(json_array_size(a), json_array_size(b));
        for (size_t i = 0; i < json_array_size(a); i++) n += same_numbers(json_array_get(a, i), json_array_get(b, i), tol);
    } else if (json_is_object(a)) {
        const char *k;
        json_t *v;
        json_object_foreach(a, k, v) n += same_numbers(v, json_object_get(b, k), tol);
    }
    return n;
}

/* A JSON file, or a JSON-lines file as an array of its lines. */
static json_t *load(const char *path)
{
    size_t len;
    char *text = ts_read_file(path, &len);
    json_error_t je;
    json_t *j = json_loads(text, JSON_DISABLE_EOF_CHECK, &je);
    if (j && je.position < (int)len - 1) { /* JSON lines */
        json_decref(j);
        j = json_array();
        for (char *line = strtok(text, "\n"); line; line = strtok(NULL, "\n")) {
            json_t *l = json_loads(line, 0, &je);
            assert_non_null(l);
            json_array_append_new(j, l);
        }
    }
    assert_non_null(j);
    free(text);
    return j;
}

/* y up, z up and x up: the same numbers from every command. */
static void test_three_axes(void **s)
{
    (void)s;
    static const int ups[3] = {2, 3, 1};
    static const char *const names[3] = {"+y", "+z", "+x"};
    json_t *frames[3], *ann[3], *cams[3], *samples[3], *cover[3];
    for (int u = 0; u < 3; u++) {
        char name[16], file[64];
        snprintf(name, sizeof name, "take%d", u);
        char *spec = write_take(name, ups[u], ups[u]), *e = NULL;
        snprintf(file, sizeof file, "frames%d.jsonl", u);
        char *fr = ts_path(dir, file);
        const char *ex[] = {"pairs", "export", "--pair", spec, "-o", fr, NULL};
        free(ts_mimic_expect(0, &e, ex));
        char said[64]; /* a take turned upright is said; y up, mimic's own, is not */
        snprintf(said, sizeof said, "%s is up (found from the rest pose; --up to change)", names[u]);
        if (!strstr(e, said) != (u == 0)) fail_msg("export said: %s", e);
        free(e);
        frames[u] = load(fr);

        snprintf(file, sizeof file, "ann%d.json", u);
        char *an = ts_path(dir, file);
        snprintf(file, sizeof file, "cams%d.json", u);
        char *cm = ts_path(dir, file);
        const char *aa[] = {"pairs", "annotate", "--pair", spec, "--every", "4", "--views", "2", "--seed", "9", "-o", an,
                            "--cameras", cm, NULL};
        free(ts_mimic_expect(0, NULL, aa));
        ann[u] = load(an);
        cams[u] = load(cm);
        free(cm);

        snprintf(file, sizeof file, "samples%d.jsonl", u);
        char *sa = ts_path(dir, file);
        const char *sm[] = {"pairs", "sample", "--prior", spec, "--annotations", an, "--samples", "200", "--chains", "1",
                            "--restart-every", "50", "--seed", "3", "-o", sa, NULL};
        free(ts_mimic_expect(0, NULL, sm));
        samples[u] = load(sa);

        const char *cv[] = {"pairs", "coverage", "--truth", spec, "--samples", sa, "--json", NULL};
        char *o = ts_mimic_expect(0, NULL, cv);
        json_error_t je;
        cover[u] = json_loads(o, 0, &je);
        assert_non_null(cover[u]);
        free(o), free(spec), free(fr), free(an), free(sa);
    }
    /* each standing: heads above ankles in every exported frame */
    for (size_t f = 1; f < json_array_size(frames[0]); f++) {
        json_t *J = json_object_get(json_array_get(frames[1], f), "joints");
        for (int who = 0; who < 2; who++) {
            double head = json_number_value(json_array_get(json_array_get(J, 17 * who), 1));
            double ankle = json_number_value(json_array_get(json_array_get(J, 17 * who + 13), 1));
            assert_true(head > ankle + 1.0); /* metres */
        }
    }
    /* every camera above the floor (the lowest joint of the take) */
    double floor_y = INFINITY;
    for (size_t f = 1; f < json_array_size(frames[0]); f++) {
        json_t *J = json_object_get(json_array_get(frames[0], f), "joints");
        for (size_t i = 0; i < json_array_size(J); i++)
            floor_y = fmin(floor_y, json_number_value(json_array_get(json_array_get(J, i), 1)));
    }
    json_t *list = json_object_get(cams[1], "cameras");
    assert_true(json_array_size(list) >= 2 * (FRAMES / 4));
    for (size_t i = 0; i < json_array_size(list); i++)
        assert_true(json_number_value(json_array_get(json_object_get(json_array_get(list, i), "position"), 1)) > floor_y);
    for (int u = 1; u < 3; u++) {
        assert_true(same_numbers(cams[0], cams[u], 1e-6) > 2 * (FRAMES / 4) * 12);
        assert_true(same_numbers(frames[0], frames[u], 1e-5) >= FRAMES * 34 * 3);
        assert_true(same_numbers(ann[0], ann[u], 1e-4) > 100);
        assert_true(same_numbers(samples[0], samples[u], 1e-4) > 200 * 34 * 3);
        assert_int_equal(same_numbers(cover[0], cover[u], 1e-6), 6); /* truth, samples, D_I, D_C, D_S, limbs */
    }
    for (int u = 0; u < 3; u++)
        json_decref(frames[u]), json_decref(ann[u]), json_decref(cams[u]), json_decref(samples[u]), json_decref(cover[u]);
}

/* --up is taken as given, and said nothing about; wrong, it lays the take
 * down. Bad input is refused in one line. */
static void test_override_and_refusals(void **s)
{
    (void)s;
    char *spec = write_take("z", 3, 3), *fr = ts_path(dir, "given.jsonl"), *e = NULL;
    const char *given[] = {"pairs", "export", "--pair", spec, "--up", "z", "-o", fr, NULL};
    free(ts_mimic_expect(0, &e, given));
    assert_null(strstr(e, "is up"));
    free(e);
    const char *wrong[] = {"pairs", "export", "--pair", spec, "--up", "y", "-o", fr, NULL};
    free(ts_mimic_expect(0, NULL, wrong));
    json_t *j = load(fr);
    json_t *J = json_object_get(json_array_get(j, 1), "joints");
    double head_z = json_number_value(json_array_get(json_array_get(J, 0), 2));
    double ankle_z = json_number_value(json_array_get(json_array_get(J, 13), 2));
    assert_true(head_z - ankle_z > 1.0); /* as written: standing along z, mimic's y ignored */
    json_decref(j);

    const char *bad[] = {"pairs", "export", "--pair", spec, "--up", "w", "-o", fr, NULL};
    free(ts_mimic_expect(2, &e, bad));
    assert_non_null(strstr(e, "mimic pairs export: --up 'w': give x, y, z, -x, -y or -z"));
    assert_null(strchr(strchr(e, '\n') + 1, '\n')); /* one line */
    free(e);

    char *mixed = write_take("mixed", 3, 2);
    const char *mx[] = {"pairs", "export", "--pair", mixed, "-o", fr, NULL};
    free(ts_mimic_expect(1, &e, mx));
    assert_non_null(strstr(e, "mixed_a.bvh is +z up and "));
    assert_non_null(strstr(e, "mixed_b.bvh +y up: give --up"));
    free(e);
    /* --up settles it (the second file then lies down, as told) */
    const char *mx2[] = {"pairs", "export", "--pair", mixed, "--up", "z", "-o", fr, NULL};
    free(ts_mimic_expect(0, NULL, mx2));

    /* a take whose skeleton stands along no axis, in its rest pose or its frames: every offset zero */
    char *flat[2];
    for (int who = 0; who < 2; who++) {
        char *text = take_text(who), *p = text;
        while ((p = strstr(p, "OFFSET "))) { /* "OFFSET a b c" -> zeros, the line's length kept */
            char *e = strchr(p, '\n');
            for (char *q = p + 7; q < e; q++)
                if (*q != ' ') *q = '0';
            p = e;
        }
        flat[who] = ts_path(dir, who ? "flat_b.bvh" : "flat_a.bvh");
        assert_int_equal(ts_write_file(flat[who], text, strlen(text)), 0);
        free(text);
    }
    char flat_spec[8192];
    snprintf(flat_spec, sizeof flat_spec, "%s,%s", flat[0], flat[1]);
    const char *fl[] = {"pairs", "export", "--pair", flat_spec, "--unit", "1", "-o", fr, NULL};
    free(ts_mimic_expect(1, &e, fl));
    assert_non_null(strstr(e, "flat_a.bvh: cannot tell which way is up"));
    assert_non_null(strstr(e, "give --up x|y|z|-x|-y|-z"));
    free(e);

    /* vest simulate: a bad --up, and an up along the motion's left-right axis */
    char *zfile = ts_path(dir, "z_a.bvh"), *rec = ts_path(dir, "z.rec");
    const char *v1[] = {"vest", "simulate", "--motion", zfile, "--up", "q", "--out", rec, NULL};
    free(ts_mimic_expect(2, &e, v1));
    assert_non_null(strstr(e, "mimic vest simulate: --up: give x, y, z, -x, -y or -z"));
    free(e);
    const char *v2[] = {"vest", "simulate", "--motion", zfile, "--up", "x", "--out", rec, NULL};
    free(ts_mimic_expect(1, &e, v2));
    assert_non_null(strstr(e, "mimic vest simulate: up +x is the motion's left-right axis"));
    free(e);
    const char *v3[] = {"vest", "simulate", "--motion", zfile, "--out", rec, NULL};
    free(ts_mimic_expect(0, &e, v3));
    assert_non_null(strstr(e, "z_a.bvh: +z is up (the rest pose's; --up to change)"));
    free(e);
    free(flat[0]), free(flat[1]), free(zfile), free(rec);
    free(spec), free(mixed), free(fr);
}

/* The orientation reader: a z-up file gives the y-up file's orientations,
 * says +z; set_up turns it as told and back. */
static void test_vest_motion_axes(void **s)
{
    (void)s;
    char *y = take_text(0), *z = bt_turn(y, 3), *x = bt_turn(y, -1);
    mim_vest_motion_t my = {0}, mz = {0}, mx = {0};
    mim_error_t err = {0};
    assert_int_equal(mim_vest_motion_parse_bvh(&my, y, strlen(y), "y.bvh", &err), 0);
    assert_int_equal(mim_vest_motion_parse_bvh(&mz, z, strlen(z), "z.bvh", &err), 0);
    assert_int_equal(mim_vest_motion_parse_bvh(&mx, x, strlen(x), "x.bvh", &err), 0);
    assert_int_equal(my.up, 2), assert_int_equal(mz.up, 3), assert_int_equal(mx.up, -1);
    double most = 0;
    for (size_t i = 0; i < (size_t)FRAMES * MIM_VEST_SEGMENTS; i++) {
        const mim_quat a = my.q[i], b = mz.q[i], c = mx.q[i];
        most = fmax(most, fmax(fabs(a.x - b.x) + fabs(a.y - b.y) + fabs(a.z - b.z) + fabs(a.w - b.w),
                               fabs(a.x - c.x) + fabs(a.y - c.y) + fabs(a.z - c.z) + fabs(a.w - c.w)));
    }
    assert_true(most < 1e-9);
    assert_true(fabs(my.rest_arm_deg - mz.rest_arm_deg) < 1e-9);
    /* told y, the z-up file lies: its orientations differ; told z again, they are back */
    assert_int_equal(mim_vest_motion_set_up(&mz, 2, &err), 0);
    double moved = 0;
    for (size_t i = 0; i < (size_t)FRAMES * MIM_VEST_SEGMENTS; i++)
        moved = fmax(moved, fabs(my.q[i].y - mz.q[i].y) + fabs(my.q[i].z - mz.q[i].z));
    assert_true(moved > 0.05);
    assert_int_equal(mim_vest_motion_set_up(&mz, 3, &err), 0);
    for (size_t i = 0; i < (size_t)FRAMES * MIM_VEST_SEGMENTS; i++)
        assert_true(fabs(my.q[i].x - mz.q[i].x) + fabs(my.q[i].y - mz.q[i].y) + fabs(my.q[i].z - mz.q[i].z) +
                        fabs(my.q[i].w - mz.q[i].w) < 1e-9);
    /* up along the hips' axis is refused; no axis at all too */
    assert_int_equal(mim_vest_motion_set_up(&mz, 1, &err), MIM_EFORMAT);
    assert_non_null(strstr(mim_error_text(&err), "left-right axis"));
    assert_int_equal(mim_vest_motion_set_up(&mz, 7, &err), MIM_EINVAL);
    mim_vest_motion_free(&my), mim_vest_motion_free(&mz), mim_vest_motion_free(&mx);
    free(y), free(z), free(x);
}

/* The joint reader's up: from the rest pose when it stands, else from the
 * frames (a rest pose with the head at the feet), 0 when neither tells. */
static void test_joint_up_fallback(void **s)
{
    (void)s;
    float rest[3 * 3] = {0, 0, 0, 0, 0, 0, 0, 0, 0}; /* head, feet: all at one point */
    float pos[2 * 3 * 3] = {-1.7f, 0.1f, 0, 0, 0, 0.1f, 0, 0, -0.1f, /* head along -x of the feet */
                            -1.6f, -0.2f, 0, 0, 0, 0.1f, 0, 0, -0.1f};
    char names[3][64] = {"Head", "LeftFoot", "RightFoot"};
    int32_t parent[3] = {-1, 0, 0};
    mim_vest_joint_motion_t m = {3, 2, 0.1, names, parent, pos, rest};
    int from_rest = 1;
    assert_int_equal(mim_vest_joint_motion_up(&m, 0, 1, 2, &from_rest), -1);
    assert_int_equal(from_rest, 0);
    rest[1] = 1.8f; /* a standing rest pose decides */
    assert_int_equal(mim_vest_joint_motion_up(&m, 0, 1, 2, &from_rest), 2);
    assert_int_equal(from_rest, 1);
    rest[1] = 0;
    pos[9] = 1.6f; /* frames that disagree (-x, then +x): no answer */
    assert_int_equal(mim_vest_joint_motion_up(&m, 0, 1, 2, &from_rest), 0);
    assert_int_equal(mim_vest_joint_motion_up(&m, 0, 1, 7, &from_rest), 0); /* a joint out of range */
}

/* Cameras never under the floor: a pair lying on it (push-ups), drawn 300
 * times, and a video camera following a pair that goes down to it. */
static void test_cameras_above_floor(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 4, 0);
    double lying[3 * MIM_PAIR_JOINTS], standing[3 * MIM_PAIR_JOINTS];
    for (int i = 0; i < MIM_PAIR_JOINTS; i++) {
        lying[3 * i] = 2 * mim_rng_unit(&r), lying[3 * i + 1] = 0.3 * mim_rng_unit(&r);
        lying[3 * i + 2] = (i < 17 ? 0 : 1) + 0.4 * mim_rng_unit(&r);
        standing[3 * i] = lying[3 * i + 2], standing[3 * i + 1] = 1.8 * lying[3 * i] / 2, standing[3 * i + 2] = lying[3 * i];
    }
    for (int k = 0; k < 300; k++) {
        mim_pairs_camera_t cam;
        assert_int_equal(mim_pairs_camera_random(&r, lying, &cam), 0);
        assert_true(cam.position[1] >= 0.3 - 1e-9); /* the lowest joint is at y >= 0 */
        assert_int_equal(mim_pairs_camera_random(&r, standing, &cam), 0);
        mim_pairs_camera_follow(&cam, lying);
        assert_true(cam.position[1] >= 0.3 - 1e-9);
    }
}

int main(void)
{
    dir = ts_tempdir("pairs_up");
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_three_axes),
        cmocka_unit_test(test_override_and_refusals),
        cmocka_unit_test(test_vest_motion_axes),
        cmocka_unit_test(test_joint_up_fallback),
        cmocka_unit_test(test_cameras_above_floor),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    ts_rmtree(dir);
    free(dir);
    return rc;
}
