/* 2D annotations of pose-pairs as a person would click them on photos
 * (issue 14, the input of seed 002's lifting): random perspective cameras
 * around a pose-pair, the projection of its joints, Gaussian pixel noise.
 * Choices (the paper annotates real video): a camera looks at the pair's
 * centre from 3 to 8 m away, from any side (azimuth uniform), from 10
 * degrees below to 35 above the horizon, upright (no roll), with a
 * 1920 x 1080 image and a focal length of 1000 to 1800 pixels (a 47 to 88
 * degree horizontal field of view, phone to wide lens); a camera that
 * leaves a joint behind it or outside the image is drawn again. No camera
 * stands under the floor: one lower than MIN_HEIGHT above the pair's lowest
 * joint is raised to that height and aimed at the centre again (a low
 * tripod). A video camera keeps its offset from the pair's centre and its
 * lens from frame to frame (mim_pairs_camera_follow), raised likewise. */
#include "mim_sample.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static mim_vec3 centre(const double *joints)
{
    mim_vec3 c = {0, 0, 0};
    for (int i = 0; i < MIM_PAIR_JOINTS; i++) c = mim_v3_add(c, mim_v3(joints[3 * i], joints[3 * i + 1], joints[3 * i + 2]));
    return mim_v3_scale(c, 1.0 / MIM_PAIR_JOINTS);
}

#define MIN_HEIGHT 0.3 /* metres above the pair's lowest joint: the floor, near enough */

static double floor_of(const double *joints)
{
    double y = joints[1];
    for (int i = 1; i < MIM_PAIR_JOINTS; i++) y = fmin(y, joints[3 * i + 1]);
    return y;
}

/* cam at pos, upright (no roll), looking at c from there. */
static void aim(mim_pairs_camera_t *cam, mim_vec3 pos, mim_vec3 c)
{
    mim_vec3 fwd = mim_v3_normalize(mim_v3_sub(c, pos));
    mim_vec3 right = mim_v3_normalize(mim_v3_cross(fwd, mim_v3(0, 1, 0)));
    mim_vec3 down = mim_v3_cross(fwd, right);
    cam->position[0] = pos.x, cam->position[1] = pos.y, cam->position[2] = pos.z;
    cam->dist = mim_v3_norm(mim_v3_sub(c, pos));
    double rows[3][3] = {{right.x, right.y, right.z}, {down.x, down.y, down.z}, {fwd.x, fwd.y, fwd.z}};
    memcpy(cam->R, rows, sizeof rows);
}

int mim_pairs_project(const mim_pairs_camera_t *cam, const double *joints, double *uv)
{
    int inside = 1;
    for (int i = 0; i < MIM_PAIR_JOINTS; i++) {
        double p[3], q[3] = {0, 0, 0};
        for (int c = 0; c < 3; c++) p[c] = joints[3 * i + c] - cam->position[c];
        /* camera axes are the rows of R: x right, y down, z forward */
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) q[r] += cam->R[3 * r + c] * p[c];
        if (!(q[2] > 1e-3)) {
            inside = 0;
            uv[2 * i] = uv[2 * i + 1] = NAN;
            continue;
        }
        uv[2 * i] = cam->focal_px * q[0] / q[2] + cam->cx;
        uv[2 * i + 1] = cam->focal_px * q[1] / q[2] + cam->cy;
        if (uv[2 * i] < 0 || uv[2 * i] > cam->width || uv[2 * i + 1] < 0 || uv[2 * i + 1] > cam->height) inside = 0;
    }
    return inside;
}

int mim_pairs_camera_follow(mim_pairs_camera_t *cam, const double *joints)
{
    /* the pair's centre sits on the optical axis at the camera's distance:
     * move the camera by the centre's motion */
    mim_vec3 c = centre(joints), fwd = mim_v3(cam->R[6], cam->R[7], cam->R[8]);
    mim_vec3 pos = mim_v3(cam->position[0], cam->position[1], cam->position[2]);
    mim_vec3 old = mim_v3_add(pos, mim_v3_scale(fwd, cam->dist));
    pos = mim_v3_add(pos, mim_v3_sub(c, old));
    cam->position[0] = pos.x, cam->position[1] = pos.y, cam->position[2] = pos.z;
    const double low = floor_of(joints) + MIN_HEIGHT;
    if (pos.y < low) /* the pair went down (a crouch, push-ups): the camera stays above the floor */
        pos.y = low, aim(cam, pos, c);
    double uv[2 * MIM_PAIR_JOINTS];
    return mim_pairs_project(cam, joints, uv);
}

int mim_pairs_camera_random(mim_rng_t *rng, const double *joints, mim_pairs_camera_t *cam)
{
    mim_vec3 c = centre(joints);
    double uv[2 * MIM_PAIR_JOINTS];
    for (int attempt = 0; attempt < 1000; attempt++) {
        double dist = 3.0 + 5.0 * mim_rng_unit(rng), az = 2 * M_PI * mim_rng_unit(rng);
        double el = (-10.0 + 45.0 * mim_rng_unit(rng)) * M_PI / 180.0;
        memset(cam, 0, sizeof *cam);
        cam->width = 1920, cam->height = 1080, cam->cx = 960, cam->cy = 540;
        cam->focal_px = 1000.0 + 800.0 * mim_rng_unit(rng);
        /* up is y: the camera sits at the centre plus dist along (az, el) */
        mim_vec3 dir = mim_v3(cos(el) * sin(az), sin(el), cos(el) * cos(az));
        mim_vec3 pos = mim_v3_add(c, mim_v3_scale(dir, dist));
        pos.y = fmax(pos.y, floor_of(joints) + MIN_HEIGHT);
        aim(cam, pos, c);
        if (mim_pairs_project(cam, joints, uv)) return 0;
    }
    return MIM_ENOTFOUND;
}

/* Grows every array of a (and *cams) to hold cap annotations. */
static int reserve(mim_pairs_annotations_t *a, mim_pairs_camera_t **cams, size_t cap)
{
    uint32_t *t1 = realloc(a->take, cap * sizeof *t1);
    if (t1) a->take = t1;
    uint32_t *t2 = t1 ? realloc(a->frame, cap * sizeof *t2) : NULL;
    if (t2) a->frame = t2;
    uint32_t *t3 = t2 ? realloc(a->view, cap * sizeof *t3) : NULL;
    if (t3) a->view = t3;
    uint32_t *t4 = t3 ? realloc(a->shot, cap * sizeof *t4) : NULL;
    if (t4) a->shot = t4;
    double *pp = t4 ? realloc(a->points, cap * 2 * MIM_PAIR_JOINTS * sizeof *pp) : NULL;
    if (pp) a->points = pp;
    if (!pp) return MIM_ENOMEM;
    if (!cams) return 0;
    mim_pairs_camera_t *cc = realloc(*cams, cap * sizeof *cc);
    if (!cc) return MIM_ENOMEM;
    *cams = cc;
    return 0;
}

int mim_pairs_annotate_take(const double *frames, uint32_t n, uint32_t first, uint32_t every, uint32_t take,
                            const mim_pairs_annotate_options_t *o, mim_pairs_annotations_t *a,
                            mim_pairs_camera_t **cams, uint32_t *shots, uint32_t *bad_frame)
{
    if (!o->views || o->views > MIM_PAIRS_ANNOTATE_MAX_VIEWS) return MIM_EINVAL;
    if ((uint64_t)a->n + (uint64_t)n * o->views > MIM_PAIRS_ANNOTATIONS_MAX) return MIM_EUNSUPPORTED;
    if (reserve(a, cams, (size_t)a->n + (size_t)n * o->views)) return MIM_ENOMEM;
    a->width = 1920, a->height = 1080; /* mim_pairs_camera_random's image */
    /* per view: its current shot, and the shot's camera */
    mim_pairs_camera_t cam, *shot_cam = malloc(o->views * sizeof *shot_cam);
    uint32_t *shot_of = malloc(o->views * sizeof *shot_of);
    int rc = shot_cam && shot_of ? 0 : MIM_ENOMEM;
    for (uint32_t v = 0; v < o->views && !rc; v++) shot_of[v] = MIM_PAIRS_NO_SHOT;
    for (uint32_t i = 0; i < n && !rc; i++)
        for (uint32_t v = 0; v < o->views && !rc; v++) {
            uint32_t frame = first + i * every;
            /* one generator stream per (take, frame, view): the same seed, the same bytes */
            mim_rng_t rng;
            mim_rng_seed(&rng, o->seed, ((uint64_t)take << 48) ^ ((uint64_t)frame << 16) ^ v);
            const double *joints = frames + (size_t)i * 3 * MIM_PAIR_JOINTS;
            /* a video's camera follows the pair; one that loses it ends its shot */
            if (o->video && shot_of[v] != MIM_PAIRS_NO_SHOT && mim_pairs_camera_follow(&shot_cam[v], joints)) {
                cam = shot_cam[v];
            } else if (mim_pairs_camera_random(&rng, joints, &cam)) {
                if (bad_frame) *bad_frame = frame;
                rc = MIM_ENOTFOUND;
                break;
            } else {
                shot_cam[v] = cam;
                shot_of[v] = o->video ? (*shots)++ : MIM_PAIRS_NO_SHOT;
            }
            double *uv = a->points + (size_t)a->n * 2 * MIM_PAIR_JOINTS;
            mim_pairs_project(&cam, joints, uv);
            for (int k = 0; k < 2 * MIM_PAIR_JOINTS; k++) uv[k] += o->noise_px * mim_rng_gauss(&rng);
            a->take[a->n] = take, a->frame[a->n] = frame, a->view[a->n] = v, a->shot[a->n] = shot_of[v];
            if (cams) (*cams)[a->n] = cam;
            a->n++;
        }
    free(shot_cam), free(shot_of);
    return rc;
}
