/* Tests of vest/'s joint-position motion reader (issue 14, two-person
 * pose-pairs): world joint positions of a BVH (and ASF/AMC) with the root
 * translation kept, worked out by hand on tiny motions written here; the
 * orientation reader on the same text; line-naming errors; and, when
 * ../shared/data has them, the CMU two-person take 11 (one world frame). */
#include "test_support.h"

#include "mim_vest_motion.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Hips (6 channels, OFFSET 1 2 3) with LeftUpLeg -> LeftLeg, RightUpLeg and
 * Head; the two upper legs have 3 rotation channels, LeftLeg and Head none.
 * Line numbers matter: frame k (0-based) is on line 32 + k. */
static const char *const tiny_lines[] = {
    "HIERARCHY",                                                              /* 1 */
    "ROOT Hips",                                                              /* 2 */
    "{",                                                                      /* 3 */
    "  OFFSET 1 2 3",                                                         /* 4 */
    "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation", /* 5 */
    "  JOINT LeftUpLeg",                                                      /* 6 */
    "  {",                                                                    /* 7 */
    "    OFFSET 2 0 0",                                                       /* 8 */
    "    CHANNELS 3 Zrotation Xrotation Yrotation",                           /* 9 */
    "    JOINT LeftLeg",                                                      /* 10 */
    "    {",                                                                  /* 11 */
    "      OFFSET 0 -4 0",                                                    /* 12 */
    "      CHANNELS 0",                                                       /* 13 */
    "      End Site",                                                         /* 14 */
    "      {",                                                                /* 15 */
    "        OFFSET 0 -4 0",                                                  /* 16 */
    "      }",                                                                /* 17 */
    "    }",                                                                  /* 18 */
    "  }",                                                                    /* 19 */
    "  JOINT RightUpLeg",                                                     /* 20 */
    "  {",                                                                    /* 21 */
    "    OFFSET -2 0 0",                                                      /* 22 */
    "    CHANNELS 3 Zrotation Xrotation Yrotation",                           /* 23 */
    "    End Site { OFFSET 0 -8 0 }",                                         /* 24 */
    "  }",                                                                    /* 25 */
    "  JOINT Head",                                                           /* 26 */
    "  { OFFSET 0 6 0 CHANNELS 0 End Site { OFFSET 0 1 0 } }",                /* 27 */
    "}",                                                                      /* 28 */
    "MOTION",                                                                 /* 29 */
    "Frames: 3",                                                              /* 30 */
    "Frame Time: 0.04",                                                       /* 31 */
    /* root X Y Z, Zrot Xrot Yrot | LeftUpLeg Z X Y | RightUpLeg Z X Y */
    "0 0 0 0 0 0   0 0 0   0 0 0",                                            /* 32: frame 0, the rest pose */
    "10 0 -5 0 0 0   90 0 0   0 0 0",                                         /* 33: frame 1 */
    "0 5 0 90 0 0   -90 0 0   0 30 0",                                        /* 34: frame 2 */
    NULL,
};
#define TINY_JOINTS 5
#define TINY_FRAMES 3

/* Positions by hand (joints in file order: Hips, LeftUpLeg, LeftLeg,
 * RightUpLeg, Head). Frame 0: offsets added up from the root's OFFSET.
 * Frame 1: the root moves by (10, 0, -5); LeftUpLeg turns 90 degrees about
 * Z, which takes LeftLeg's OFFSET (0, -4, 0) to (4, 0, 0). Frame 2: the root
 * at (1, 7, 3) turns 90 about Z, which takes (2,0,0) to (0,2,0), (-2,0,0) to
 * (0,-2,0) and (0,6,0) to (-6,0,0); LeftUpLeg turns back by -90, so LeftLeg
 * hangs straight down again; RightUpLeg's X turn moves no joint (it has no
 * child joint). */
static const double tiny_want[TINY_FRAMES][TINY_JOINTS][3] = {
    {{1, 2, 3}, {3, 2, 3}, {3, -2, 3}, {-1, 2, 3}, {1, 8, 3}},
    {{11, 2, -2}, {13, 2, -2}, {17, 2, -2}, {9, 2, -2}, {11, 8, -2}},
    {{1, 7, 3}, {1, 9, 3}, {1, 5, 3}, {1, 5, 3}, {-5, 7, 3}},
};

/* The tiny motion joined with `eol`; line `bad_line` (1-based, 0 none)
 * replaced by `bad`. malloc'd. */
static char *tiny_text(const char *eol, int bad_line, const char *bad)
{
    size_t cap = 4096, n = 0;
    char *t = malloc(cap);
    assert_non_null(t);
    for (int i = 0; tiny_lines[i]; i++) {
        const char *l = i + 1 == bad_line ? bad : tiny_lines[i];
        n += (size_t)snprintf(t + n, cap - n, "%s%s", l, eol);
        assert_true(n < cap);
    }
    return t;
}

static const float *pos_at(const mim_vest_joint_motion_t *m, uint32_t f, uint32_t j)
{
    return m->positions + 3 * ((size_t)f * m->n_joints + j);
}

static double dist(const float *a, const float *b)
{
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

static int all_zero(const void *p, size_t n)
{
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++)
        if (b[i]) return 0;
    return 1;
}

static void check_tiny(const mim_vest_joint_motion_t *m)
{
    static const char *const names[TINY_JOINTS] = {"Hips", "LeftUpLeg", "LeftLeg", "RightUpLeg", "Head"};
    static const int32_t parents[TINY_JOINTS] = {-1, 0, 1, 0, 0};
    assert_int_equal(m->n_joints, TINY_JOINTS);
    assert_int_equal(m->n_frames, TINY_FRAMES);
    assert_true(fabs(m->frame_time - 0.04) < 1e-12);
    for (uint32_t j = 0; j < TINY_JOINTS; j++) {
        assert_string_equal(m->name[j], names[j]);
        assert_int_equal(m->parent[j], parents[j]);
    }
    for (uint32_t f = 0; f < TINY_FRAMES; f++)
        for (uint32_t j = 0; j < TINY_JOINTS; j++)
            for (int c = 0; c < 3; c++) {
                double got = pos_at(m, f, j)[c], want = tiny_want[f][j][c];
                if (!(fabs(got - want) < 1e-5))
                    fail_msg("frame %u joint %s axis %d: %g, want %g", f, names[j], c, got, want);
            }
}

/* ------------------------------------------------------------ by hand */

static void test_joint_positions_by_hand(void **state)
{
    (void)state;
    mim_error_t err = {0};
    mim_vest_joint_motion_t m;
    for (int crlf = 0; crlf < 2; crlf++) {
        char *text = tiny_text(crlf ? "\r\n" : "\n", 0, NULL);
        int rc = mim_vest_joint_motion_parse_bvh(&m, text, strlen(text), "tiny.bvh", &err);
        if (rc) fail_msg("%s", err.msg);
        check_tiny(&m);
        mim_vest_joint_motion_free(&m);
        assert_true(all_zero(&m, sizeof m));
        free(text);
    }
    /* the same through a file */
    char *dir = ts_tempdir("vest_motion"), *path = ts_path(dir, "tiny.bvh"), *text = tiny_text("\r\n", 0, NULL);
    assert_int_equal(ts_write_file(path, text, strlen(text)), 0);
    int rc = mim_vest_joint_motion_read_bvh(&m, path, &err);
    if (rc) fail_msg("%s", err.msg);
    check_tiny(&m);
    mim_vest_joint_motion_free(&m);
    mim_vest_joint_motion_free(&m); /* zeroed: again is fine */
    mim_vest_joint_motion_free(NULL);
    free(text), free(path);
    ts_rmtree(dir);
    free(dir);
}

/* Position channels in any order (Zposition gives z), and on a non-root
 * joint: added to its OFFSET, then turned by its parent. No head or legs:
 * the joint reader needs no particular joints, the orientation reader does. */
static void test_position_channels(void **state)
{
    (void)state;
    const char *text = "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n"
                       " CHANNELS 4 Zposition Yposition Xposition Zrotation\n"
                       " JOINT Arm\n {\n  OFFSET 1 0 0\n  CHANNELS 1 Yposition\n"
                       "  End Site\n  {\n   OFFSET 1 0 0\n  }\n }\n}\n"
                       "MOTION\nFrames: 2\nFrame Time: 0.5\n"
                       "0 0 0 0 0\n"
                       "3 2 1 90 7\n";
    mim_vest_joint_motion_t m;
    mim_error_t err = {0};
    int rc = mim_vest_joint_motion_parse_bvh(&m, text, strlen(text), NULL, &err);
    if (rc) fail_msg("%s", err.msg);
    assert_int_equal(m.n_joints, 2);
    assert_int_equal(m.n_frames, 2);
    /* frame 0: Arm at its OFFSET */
    const float want0[2][3] = {{0, 0, 0}, {1, 0, 0}};
    /* frame 1: root at (x, y, z) = (1, 2, 3), turned 90 about Z; Arm's
     * OFFSET plus its Yposition, (1, 7, 0), turned to (-7, 1, 0) */
    const float want1[2][3] = {{1, 2, 3}, {-6, 3, 3}};
    for (int j = 0; j < 2; j++) {
        assert_true(dist(pos_at(&m, 0, (uint32_t)j), want0[j]) < 1e-5);
        assert_true(dist(pos_at(&m, 1, (uint32_t)j), want1[j]) < 1e-5);
    }
    mim_vest_joint_motion_free(&m);
    mim_vest_motion_t o;
    assert_int_equal(mim_vest_motion_parse_bvh(&o, text, strlen(text), NULL, &err), MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "head"));
}

/* ------------------------------------------------------------ the orientation reader on the same text */

static double qdot(mim_quat a, mim_quat b) { return a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w; }

static void test_orientations_same_text(void **state)
{
    (void)state;
    mim_error_t err = {0};
    char *lf = tiny_text("\n", 0, NULL), *crlf = tiny_text("\r\n", 0, NULL);
    /* the same motion standing still: the root's translation zeroed */
    char *still = tiny_text("\n", 33, "0 0 0 0 0 0   90 0 0   0 0 0");
    char *p = strstr(still, "0 5 0 90");
    assert_non_null(p);
    p[2] = '0';
    mim_vest_motion_t a, b, c;
    int rc = mim_vest_motion_parse_bvh(&a, lf, strlen(lf), "tiny.bvh", &err);
    if (rc) fail_msg("%s", err.msg);
    assert_int_equal(mim_vest_motion_parse_bvh(&b, crlf, strlen(crlf), "tiny.bvh", &err), 0);
    assert_int_equal(mim_vest_motion_parse_bvh(&c, still, strlen(still), "still.bvh", &err), 0);
    assert_int_equal(a.n_frames, TINY_FRAMES);
    assert_true(fabs(a.frame_time - 0.04) < 1e-12);
    assert_string_equal(a.joint[MIM_VEST_L_THIGH], "LeftUpLeg");
    assert_string_equal(a.joint[MIM_VEST_PELVIS], "Hips");
    /* CRLF and LF give the same orientations; the orientation reader drops
     * the translation, so the still motion gives them too */
    size_t qn = sizeof *a.q * MIM_VEST_SEGMENTS * TINY_FRAMES;
    assert_memory_equal(a.q, b.q, qn);
    assert_memory_equal(a.q, c.q, qn);
    assert_memory_equal(a.have, b.have, sizeof a.have);

    /* Y up and +X left already: the avatar frame is the motion's, so a
     * segment's orientation is its joint's world rotation, by hand */
    const mim_quat z90 = mim_quat_axis_angle(mim_v3(0, 0, 1), M_PI / 2), id = mim_quat_identity();
    const mim_quat *q1 = a.q + MIM_VEST_SEGMENTS, *q2 = a.q + 2 * MIM_VEST_SEGMENTS;
    assert_true(fabs(fabs(qdot(q1[MIM_VEST_PELVIS], id)) - 1) < 1e-9);
    assert_true(fabs(fabs(qdot(q1[MIM_VEST_L_THIGH], z90)) - 1) < 1e-9);
    assert_true(fabs(fabs(qdot(q2[MIM_VEST_PELVIS], z90)) - 1) < 1e-9);
    assert_true(fabs(fabs(qdot(q2[MIM_VEST_L_THIGH], id)) - 1) < 1e-9);
    assert_true(fabs(fabs(qdot(q2[MIM_VEST_HEAD], z90)) - 1) < 1e-9);

    /* and both readers agree: the left thigh's orientation turns its rest
     * bone (LeftUpLeg -> LeftLeg) into the bone between the two positions */
    mim_vest_joint_motion_t j;
    assert_int_equal(mim_vest_joint_motion_parse_bvh(&j, lf, strlen(lf), "tiny.bvh", &err), 0);
    const float *r0 = pos_at(&j, 0, 1), *r1 = pos_at(&j, 0, 2);
    mim_vec3 rest = mim_v3(r1[0] - r0[0], r1[1] - r0[1], r1[2] - r0[2]);
    for (uint32_t f = 0; f < TINY_FRAMES; f++) {
        mim_vec3 bone = mim_quat_rotate(a.q[(size_t)f * MIM_VEST_SEGMENTS + MIM_VEST_L_THIGH], rest);
        const float *u = pos_at(&j, f, 1), *l = pos_at(&j, f, 2);
        float want[3] = {(float)bone.x, (float)bone.y, (float)bone.z}, got[3] = {l[0] - u[0], l[1] - u[1], l[2] - u[2]};
        assert_true(dist(got, want) < 1e-5);
    }
    mim_vest_joint_motion_free(&j);
    mim_vest_motion_free(&a), mim_vest_motion_free(&b), mim_vest_motion_free(&c);
    free(lf), free(crlf), free(still);
}

/* ------------------------------------------------------------ errors name the line */

static void expect_error(const char *text, size_t len, int code, const char *where, const char *what)
{
    mim_vest_joint_motion_t m;
    memset(&m, 0x5A, sizeof m); /* error leaves it zeroed, whatever it held */
    mim_error_t err = {0};
    int rc = mim_vest_joint_motion_parse_bvh(&m, text, len, "tiny.bvh", &err);
    if (rc != code) fail_msg("rc %d (%s), want %d", rc, err.msg, code);
    if (!strstr(err.msg, where) || (what && !strstr(err.msg, what)))
        fail_msg("'%s' does not say '%s' and '%s'", err.msg, where, what ? what : "");
    assert_true(all_zero(&m, sizeof m));
    mim_vest_joint_motion_free(&m);
    /* the orientation reader parses with the same code: the same error */
    mim_vest_motion_t o;
    mim_error_t err2 = {0};
    assert_int_equal(mim_vest_motion_parse_bvh(&o, text, len, "tiny.bvh", &err2), code);
    assert_string_equal(err2.msg, err.msg);
}

static void test_errors_name_line(void **state)
{
    (void)state;
    for (int crlf = 0; crlf < 2; crlf++) {
        const char *eol = crlf ? "\r\n" : "\n";
        /* a value of frame 1 (line 33) is not a number */
        char *t = tiny_text(eol, 33, "10 0 -5 0 0 0   9O 0 0   0 0 0");
        expect_error(t, strlen(t), MIM_EFORMAT, "tiny.bvh:33:", "'9O'");
        free(t);
        /* cut inside frame 2 (line 34): ends before a number */
        t = tiny_text(eol, 0, NULL);
        char *cut = strstr(t, "0 5 0 90");
        assert_non_null(cut);
        expect_error(t, (size_t)(cut - t) + 6, MIM_ETRUNCATED, "tiny.bvh:34:", "ends before a number");
        /* cut inside the hierarchy (in the root's CHANNELS, line 5) */
        cut = strstr(t, "Xrotation Yrotation");
        expect_error(t, (size_t)(cut - t), MIM_ETRUNCATED, "tiny.bvh:5:", "channels end early");
        free(t);
        /* a non-number in the hierarchy: an OFFSET (line 12) */
        t = tiny_text(eol, 12, "      OFFSET 0 -four 0");
        expect_error(t, strlen(t), MIM_EFORMAT, "tiny.bvh:12:", "'-four'");
        free(t);
    }
    /* bad arguments */
    mim_vest_joint_motion_t m;
    mim_error_t err = {0};
    assert_int_equal(mim_vest_joint_motion_parse_bvh(NULL, "x", 1, NULL, &err), MIM_EINVAL);
    assert_int_equal(mim_vest_joint_motion_parse_bvh(&m, NULL, 3, NULL, &err), MIM_EINVAL);
    assert_true(all_zero(&m, sizeof m));
    assert_int_equal(mim_vest_joint_motion_parse_bvh(&m, NULL, 0, NULL, &err), MIM_ETRUNCATED);
    assert_true(all_zero(&m, sizeof m));
    /* a missing file */
    memset(&m, 0x5A, sizeof m);
    mim_error_clear(&err); /* err keeps the first error */
    assert_true(mim_vest_joint_motion_read_bvh(&m, "/nonexistent/none.bvh", &err) < 0);
    assert_non_null(strstr(err.msg, "none.bvh"));
    assert_true(all_zero(&m, sizeof m));
}

/* ------------------------------------------------------------ CMU two-person take 11 */

static int find(const mim_vest_joint_motion_t *m, const char *name)
{
    for (uint32_t j = 0; j < m->n_joints; j++)
        if (!strcmp(m->name[j], name)) return (int)j;
    return -1;
}

static void read_or_fail(mim_vest_joint_motion_t *m, const char *path)
{
    mim_error_t err = {0};
    int rc = mim_vest_joint_motion_read_bvh(m, path, &err);
    if (rc) fail_msg("%s", err.msg);
}

static void test_cmu_pair(void **state)
{
    (void)state;
    char pa[4096], pb[4096];
    snprintf(pa, sizeof pa, "%s/cmu-pairs/20_11.bvh", ts_shared_data());
    snprintf(pb, sizeof pb, "%s/cmu-pairs/21_11.bvh", ts_shared_data());
    if (access(pa, R_OK) || access(pb, R_OK)) {
        print_message("no %s/cmu-pairs: skipped\n", ts_shared_data());
        skip();
    }
    mim_vest_joint_motion_t a, b;
    read_or_fail(&a, pa);
    read_or_fail(&b, pb);
    assert_int_equal(a.n_frames, 233);
    assert_int_equal(b.n_frames, 233);
    assert_true(a.frame_time == b.frame_time);
    assert_true(fabs(a.frame_time - 1.0 / 120) < 1e-6);
    assert_true(a.n_joints > 20);
    assert_string_equal(a.name[0], "Hips");
    assert_string_equal(b.name[0], "Hips");
    for (uint32_t j = 0; j < a.n_joints; j++) assert_true(a.parent[j] < (int32_t)j);
    /* one world frame: at frame 100 the two people are close (high five),
     * yet not one on top of the other */
    double d = dist(pos_at(&a, 100, 0), pos_at(&b, 100, 0));
    print_message("Hips apart at frame 100: %.3f BVH units (%.2f m)\n", d, d * 0.0254 / 0.45);
    assert_true(d > 0.5 && d < 40);
    /* the translation is kept: both walk over the take */
    assert_true(dist(pos_at(&a, 0, 0), pos_at(&a, a.n_frames - 1, 0)) > 1);
    assert_true(dist(pos_at(&b, 0, 0), pos_at(&b, b.n_frames - 1, 0)) > 1);
    /* Y up: the head is well above the hips and the feet below, every frame */
    int ha = find(&a, "Head"), fa = find(&a, "LeftFoot");
    assert_true(ha > 0 && fa > 0);
    for (uint32_t f = 0; f < a.n_frames; f++) {
        assert_true(pos_at(&a, f, (uint32_t)ha)[1] > pos_at(&a, f, 0)[1] + 5);
        assert_true(pos_at(&a, f, (uint32_t)fa)[1] < pos_at(&a, f, 0)[1] - 5);
    }
    /* bones are rigid: a bone's length is the same in every frame */
    for (uint32_t j = 1; j < a.n_joints; j++) {
        double l0 = dist(pos_at(&a, 0, j), pos_at(&a, 0, (uint32_t)a.parent[j]));
        for (uint32_t f = 1; f < a.n_frames; f++)
            assert_true(fabs(dist(pos_at(&a, f, j), pos_at(&a, f, (uint32_t)a.parent[j])) - l0) < 1e-3 * (1 + l0));
    }
    mim_vest_joint_motion_free(&a);
    mim_vest_joint_motion_free(&b);
}

/* Subject 20's original ASF/AMC of take 11 against its BVH conversion (the
 * converter added a T-pose as BVH frame 0, so AMC frame f is BVH frame
 * f + 1): the same world positions, root translation included. */
static void test_cmu_amc(void **state)
{
    (void)state;
    char asf[4096], amc[4096], bvh[4096];
    snprintf(asf, sizeof asf, "%s/cmu-mocap/20.asf", ts_shared_data());
    snprintf(amc, sizeof amc, "%s/cmu-mocap/20_11.amc", ts_shared_data());
    snprintf(bvh, sizeof bvh, "%s/cmu-pairs/20_11.bvh", ts_shared_data());
    if (access(asf, R_OK) || access(amc, R_OK) || access(bvh, R_OK)) {
        print_message("no cmu-mocap/20.asf, 20_11.amc or cmu-pairs/20_11.bvh: skipped\n");
        skip();
    }
    mim_vest_joint_motion_t a, b;
    mim_error_t err = {0};
    int rc = mim_vest_joint_motion_read_amc(&a, asf, amc, &err);
    if (rc) fail_msg("%s", err.msg);
    read_or_fail(&b, bvh);
    assert_int_equal(a.n_frames + 1, b.n_frames);
    assert_true(fabs(a.frame_time - 1.0 / 120) < 1e-12);
    assert_string_equal(a.name[0], "root");
    assert_int_equal(a.parent[0], -1);
    /* AMC bone -> the BVH joint at the bone's start. Legs and the spine up
     * to the thorax only: the conversion has no thorax bone (its Neck sits
     * at Spine1 with OFFSET 0), so everything above it is 2.26 units lower
     * in the BVH than in the AMC. */
    static const char *const pairs[][2] = {
        {"root", "Hips"},        {"lfemur", "LeftUpLeg"}, {"ltibia", "LeftLeg"},  {"lfoot", "LeftFoot"},
        {"ltoes", "LeftToeBase"}, {"rfemur", "RightUpLeg"}, {"rtibia", "RightLeg"}, {"rfoot", "RightFoot"},
        {"upperback", "Spine"},  {"thorax", "Spine1"},
    };
    double worst = 0;
    for (size_t i = 0; i < sizeof pairs / sizeof pairs[0]; i++) {
        int ja = find(&a, pairs[i][0]), jb = find(&b, pairs[i][1]);
        if (ja < 0 || jb < 0) fail_msg("no %s / %s", pairs[i][0], pairs[i][1]);
        for (uint32_t f = 0; f < a.n_frames; f++)
            worst = fmax(worst, dist(pos_at(&a, f, (uint32_t)ja), pos_at(&b, f + 1, (uint32_t)jb)));
    }
    print_message("AMC vs BVH, worst joint distance: %.4f BVH units\n", worst);
    assert_true(worst < 0.005); /* the BVH has 4 to 5 decimals */
    /* the orientation reader still reads the same files */
    mim_vest_motion_t o;
    assert_int_equal(mim_vest_motion_read_amc(&o, asf, amc, &err), 0);
    assert_int_equal(o.n_frames, a.n_frames);
    mim_vest_motion_free(&o);
    mim_vest_joint_motion_free(&a);
    mim_vest_joint_motion_free(&b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_joint_positions_by_hand),
        cmocka_unit_test(test_position_channels),
        cmocka_unit_test(test_orientations_same_text),
        cmocka_unit_test(test_errors_name_line),
        cmocka_unit_test(test_cmu_pair),
        cmocka_unit_test(test_cmu_amc),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
