/* UDP transport: landmark frames from optical trackers or remote vests, one
 * JSON datagram each (schemas/vest-udp.schema.json):
 * {"t": microseconds, "landmarks": [[x, y, z] | null, ...]}, and the
 * segment orientations when the sender has them:
 * "orientations": {"pelvis": [x, y, z, w] | null, ...}. */
#include "transport_internal.h"

#include <errno.h>
#include <jansson.h>
#include <netdb.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

int mim__udp_open(mim_vest_transport_t *t, const char *hostport, mim_error_t *err)
{
    char host[256];
    const char *colon = strrchr(hostport, ':');
    if (!colon || (size_t)(colon - hostport) >= sizeof host || !colon[1])
        return mim_error_set(err, MIM_EINVAL, "vest: 'udp:%s' is not udp:HOST:PORT", hostport);
    memcpy(host, hostport, (size_t)(colon - hostport));
    host[colon - hostport] = 0;
    struct addrinfo hints = {0}, *ai = NULL;
    hints.ai_socktype = SOCK_DGRAM;
    hints.ai_flags = AI_PASSIVE;
    int g = getaddrinfo(host[0] ? host : NULL, colon + 1, &hints, &ai);
    if (g) return mim_error_set(err, MIM_EINVAL, "%s: %s", t->desc, gai_strerror(g));
    int fd = socket(ai->ai_family, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd < 0 || bind(fd, ai->ai_addr, ai->ai_addrlen)) {
        int e = errno;
        if (fd >= 0) close(fd);
        freeaddrinfo(ai);
        return mim_error_set(err, -e, "%s: cannot listen (%s)", t->desc, strerror(e));
    }
    freeaddrinfo(ai);
    t->sock = fd;
    return 0;
}

int mim__udp_read(mim_vest_transport_t *t, mim_vest_chunk_t *c, mim_error_t *err)
{
    struct pollfd p = {t->sock, POLLIN, 0};
    int r = poll(&p, 1, t->o.timeout_ms);
    if (r < 0) return mim_error_set(err, -errno, "%s: poll: %s", t->desc, strerror(errno));
    if (r == 0) return mim_error_set(err, -ETIMEDOUT, "%s: no data for %d ms", t->desc, t->o.timeout_ms);
    ssize_t n = recv(t->sock, t->buf, sizeof t->buf, 0);
    if (n < 0) return mim_error_set(err, -errno, "%s: read error: %s", t->desc, strerror(errno));
    c->kind = MIM_VEST_CHUNK_LANDMARKS;
    c->t_us = mim__now_us();
    c->data = t->buf, c->len = (size_t)n;
    c->restart = 0;
    return 1;
}

void mim__udp_close(mim_vest_transport_t *t)
{
    if (t->sock >= 0) close(t->sock);
    t->sock = -1;
}

int mim_vest_udp_parse_orient(const char *text, size_t len, uint64_t *t_us, float *xyz, uint8_t *present,
                              uint32_t max, uint32_t *count, mim_quat R[MIM_SEGMENTS], uint8_t have[MIM_SEGMENTS],
                              int *has_orient, mim_error_t *err)
{
    double q[4 * MIM_SEGMENTS];
    uint8_t h[MIM_SEGMENTS];
    json_error_t je;
    json_t *root = json_loadb(text, len, JSON_REJECT_DUPLICATES, &je);
    if (!root) return mim_error_set(err, MIM_EFORMAT, "udp frame:%d:%d: %s", je.line, je.column, je.text);
    int rc = 0;
    json_t *t = json_object_get(root, "t"), *lm = json_object_get(root, "landmarks");
    json_t *orient = json_object_get(root, "orientations");
    if (!json_is_object(root) || !json_is_integer(t) || json_integer_value(t) < 0 || !json_is_array(lm)) {
        rc = mim_error_set(err, MIM_EFORMAT, "udp frame: needs {\"t\": microseconds >= 0, \"landmarks\": [...]}");
        goto done;
    }
    size_t n = json_array_size(lm);
    if (n > max) {
        rc = mim_error_set(err, MIM_EFORMAT, "udp frame: %zu landmarks (at most %u)", n, max);
        goto done;
    }
    /* any count up to max: the caller matches it against its landmark map */
    rc = mim_landmark_array_parse(lm, (uint32_t)n, (uint32_t)n, "udp frame", -1, xyz, present, err);
    if (rc)
        goto done;
    if (orient) {
        rc = mim_orientations_parse(orient, "udp frame", -1, q, h, err);
        if (rc)
            goto done;
    } else {
        memset(h, 0, sizeof h);
    }
    for (int s = 0; s < MIM_SEGMENTS; s++) {
        if (R) R[s] = h[s] ? (mim_quat){q[4 * s], q[4 * s + 1], q[4 * s + 2], q[4 * s + 3]} : mim_quat_identity();
        if (have) have[s] = h[s];
    }
    if (has_orient) *has_orient = orient != NULL;
    *t_us = (uint64_t)json_integer_value(t);
    *count = (uint32_t)n;
done:
    json_decref(root);
    return rc;
}

int mim_vest_udp_parse(const char *text, size_t len, uint64_t *t_us, float *xyz, uint8_t *present, uint32_t max,
                       uint32_t *count, mim_error_t *err)
{
    return mim_vest_udp_parse_orient(text, len, t_us, xyz, present, max, count, NULL, NULL, NULL, err);
}

char *mim_vest_udp_format_orient(uint64_t t_us, const float *xyz, const uint8_t *present, uint32_t count,
                                 const mim_quat R[MIM_SEGMENTS], const uint8_t have[MIM_SEGMENTS])
{
    json_t *root = json_object(), *lm = json_array();
    if (!root || !lm) {
        json_decref(root), json_decref(lm);
        return NULL;
    }
    json_object_set_new(root, "t", json_integer((json_int_t)t_us));
    for (uint32_t i = 0; i < count; i++) {
        if (!present[i]) {
            json_array_append_new(lm, json_null());
            continue;
        }
        json_t *p = json_array();
        for (int c = 0; c < 3; c++) json_array_append_new(p, json_real(xyz[3 * i + (uint32_t)c]));
        json_array_append_new(lm, p);
    }
    json_object_set_new(root, "landmarks", lm);
    if (R) {
        json_t *o = json_object();
        for (int s = 0; o && s < MIM_SEGMENTS; s++) {
            json_t *v = json_null();
            if (!have || have[s]) {
                v = json_array();
                double c[4] = {R[s].x, R[s].y, R[s].z, R[s].w};
                for (int i = 0; i < 4; i++) json_array_append_new(v, json_real(c[i]));
            }
            json_object_set_new(o, mim_segment_names[s], v);
        }
        json_object_set_new(root, "orientations", o);
    }
    /* 9 digits: a unit quaternion reads back well within MIM_ORIENT_UNIT_TOL */
    char *s = json_dumps(root, JSON_COMPACT | JSON_REAL_PRECISION(9));
    json_decref(root);
    return s;
}

char *mim_vest_udp_format(uint64_t t_us, const float *xyz, const uint8_t *present, uint32_t count)
{
    return mim_vest_udp_format_orient(t_us, xyz, present, count, NULL, NULL);
}
