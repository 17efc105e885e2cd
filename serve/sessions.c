/* The sessions of mimic serve (issue 16): each a vest, an avatar and a
 * stream, all on the one store. A session's pipeline is a fork of the
 * service's (mim_session_fork: one LMDB environment, one index, one
 * connectivity per process; the avatar's factor and template cache are
 * the session's own), its vest loop a thread of its own, and its compute
 * goes through the service's gate (gate.c), sized to the cores.
 *
 * Lifetime: the list holds a reference to every live session, and so does
 * every lookup (a handler computing on it) and every stream client. A
 * removed session leaves the lookups at once, its loop is stopped, its
 * clients are closed from the service thread, and it is freed when the
 * last reference goes, wherever that is. */
#include "internal.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define KEY_RATE_MAX 1000.0 /* Hz, as --key-rate */

int mim__session_name_ok(const char *name)
{
    size_t n = name ? strlen(name) : 0;
    if (n < 1 || n > MIM_SERVE_SESSION_NAME_MAX)
        return 0;
    _Static_assert(MIM_SERVE_SESSION_NAME_MAX == 32, "MIM_SERVE_SESSION_NAME_RULE says 32");
    if (!isalnum((unsigned char)name[0])) return 0; /* ".", "..", "-x": no name a path could lose */
    return strspn(name, "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_.-") == n;
}

static int bad_name(const char *name, mim_error_t *err)
{
    char shown[80];
    mim__printable(name, strlen(name), shown, sizeof shown);
    return mim_error_set(err, MIM_EINVAL, "session name '%s': " MIM_SERVE_SESSION_NAME_RULE, shown);
}

/* The text of value into dst (size n): MIM_EINVAL naming the field when it
 * is empty or too long. */
static int set_field(char *dst, size_t n, const char *value, size_t len, const char *field, const char *text,
                     mim_error_t *err)
{
    if (!len || len >= n)
        return mim_error_set(err, MIM_EINVAL, "--session '%.200s': %s %s", text, field,
                             len ? "is too long" : "is empty");
    memcpy(dst, value, len), dst[len] = 0;
    return 0;
}

static int key_rate_of(const char *v, size_t len, double *out)
{
    char num[64];
    if (!len || len >= sizeof num)
        return -1;
    memcpy(num, v, len), num[len] = 0;
    char *end = NULL;
    double r = strtod(num, &end);
    if (*end || !(r > 0.0 && r <= KEY_RATE_MAX))
        return -1;
    *out = r;
    return 0;
}

int mim_serve_session_spec_parse(const char *text, mim_serve_session_spec_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    const char *colon = strchr(text, ':');
    if (!colon)
        return mim_error_set(err, MIM_EINVAL, "--session '%.200s': not NAME:vest=SPEC,avatar=MESH|ID[,key-rate=HZ]",
                             text);
    size_t nl = (size_t)(colon - text);
    if (nl <= MIM_SERVE_SESSION_NAME_MAX)
        memcpy(out->name, text, nl), out->name[nl] = 0;
    if (!mim__session_name_ok(out->name))
        return mim_error_set(err, MIM_EINVAL, "--session '%.200s': the name must be " MIM_SERVE_SESSION_NAME_RULE,
                             text);
    for (const char *p = colon + 1; *p;) {
        const char *end = strchr(p, ','), *eq = strchr(p, '=');
        if (!end)
            end = p + strlen(p);
        if (!eq || eq > end)
            return mim_error_set(err, MIM_EINVAL, "--session '%.200s': '%.*s' is not FIELD=VALUE", text,
                                 (int)(end - p > 60 ? 60 : end - p), p);
        size_t kl = (size_t)(eq - p), vl = (size_t)(end - eq - 1);
        int rc = 0;
        if (kl == 4 && !strncmp(p, "vest", 4))
            rc = set_field(out->vest, sizeof out->vest, eq + 1, vl, "vest", text, err);
        else if (kl == 6 && !strncmp(p, "avatar", 6))
            rc = set_field(out->avatar, sizeof out->avatar, eq + 1, vl, "avatar", text, err);
        else if (kl == 8 && !strncmp(p, "key-rate", 8)) {
            if (key_rate_of(eq + 1, vl, &out->key_rate))
                rc = mim_error_set(err, MIM_EINVAL, "--session '%.200s': key-rate must be a rate in (0, %g] Hz",
                                   text, KEY_RATE_MAX);
        } else
            rc = mim_error_set(err, MIM_EINVAL, "--session '%.200s': unknown field '%.*s' (vest, avatar, key-rate)",
                               text, (int)(kl > 40 ? 40 : kl), p);
        if (rc)
            return rc;
        p = *end ? end + 1 : end;
    }
    if (!out->avatar[0])
        return mim_error_set(err, MIM_EINVAL, "--session '%.200s': give avatar=MESH|ID", text);
    return 0;
}

int mim_serve_session_spec_json(const json_t *j, const char *where, mim_serve_session_spec_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    if (!json_is_object(j))
        return mim_error_set(err, MIM_EFORMAT, "%s: a session is an object with \"name\" and \"avatar\"", where);
    const char *key;
    json_t *v;
    json_object_foreach((json_t *)j, key, v)
    {
        if (strcmp(key, "name") && strcmp(key, "avatar") && strcmp(key, "vest") && strcmp(key, "key_rate")) {
            char shown[72];
            mim__printable(key, strlen(key), shown, sizeof shown);
            return mim_error_set(err, MIM_EFORMAT, "%s: unknown member \"%s\" (name, avatar, vest, key_rate)", where,
                                 shown);
        }
    }
    static const char *const names[3] = {"name", "avatar", "vest"};
    char *dst[3] = {out->name, out->avatar, out->vest};
    const size_t size[3] = {sizeof out->name, sizeof out->avatar, sizeof out->vest};
    for (int k = 0; k < 3; k++) {
        json_t *s = json_object_get(j, names[k]);
        if (!s && k == 2)
            continue;
        if (!json_is_string(s) || !json_string_length(s) || json_string_length(s) >= size[k] ||
            strlen(json_string_value(s)) != json_string_length(s)) /* a \u0000 inside */
            return mim_error_set(err, MIM_EFORMAT, "%s: \"%s\" must be a string of 1 to %zu bytes", where, names[k],
                                 size[k] - 1);
        memcpy(dst[k], json_string_value(s), json_string_length(s) + 1);
    }
    if (!mim__session_name_ok(out->name))
        return mim_error_set(err, MIM_EFORMAT, "%s: \"name\" must be " MIM_SERVE_SESSION_NAME_RULE, where);
    json_t *r = json_object_get(j, "key_rate");
    if (r && (!json_is_number(r) || !(json_number_value(r) > 0.0 && json_number_value(r) <= KEY_RATE_MAX)))
        return mim_error_set(err, MIM_EFORMAT, "%s: \"key_rate\" must be a rate in (0, %g] Hz", where, KEY_RATE_MAX);
    out->key_rate = r ? json_number_value(r) : 0.0;
    return 0;
}

/* ---- the list ---- */
static mim__vs_t *find_live(mim_serve_t *sv, const char *name)
{
    for (mim__vs_t *v = sv->sessions; v; v = v->next)
        if (!v->removed && (!name || !name[0] || !strcmp(v->name, name)))
            return v;
    return NULL;
}

mim__vs_t *mim__sessions_get(mim_serve_t *sv, const char *name)
{
    pthread_mutex_lock(&sv->sessions_lock);
    mim__vs_t *v = find_live(sv, name);
    if (v)
        v->refs++;
    pthread_mutex_unlock(&sv->sessions_lock);
    return v;
}

static void vs_free(mim__vs_t *vs)
{
    mim__loop_close(&vs->loop);
    if (vs->owned)
        mim_session_close(&vs->s);
    mim__metrics_destroy(&vs->m);
    pthread_mutex_destroy(&vs->lock);
    free(vs);
}

void mim__vs_release(mim__vs_t *vs)
{
    if (!vs)
        return;
    mim_serve_t *sv = vs->sv;
    pthread_mutex_lock(&sv->sessions_lock);
    int last = --vs->refs == 0;
    if (last)
        for (mim__vs_t **p = &sv->sessions; *p; p = &(*p)->next)
            if (*p == vs) {
                *p = vs->next;
                break;
            }
    pthread_mutex_unlock(&sv->sessions_lock);
    if (last) {
        vs_free(vs);
        if (sv->opt.on_session_freed) sv->opt.on_session_freed(sv->opt.user);
    }
}

int mim__vs_removed(mim__vs_t *vs)
{
    pthread_mutex_lock(&vs->sv->sessions_lock);
    int removed = vs->removed;
    pthread_mutex_unlock(&vs->sv->sessions_lock);
    return removed;
}

mim__vs_t **mim__sessions_all(mim_serve_t *sv, size_t *n)
{
    *n = 0;
    pthread_mutex_lock(&sv->sessions_lock);
    size_t count = 0;
    for (mim__vs_t *v = sv->sessions; v; v = v->next)
        count += !v->removed;
    mim__vs_t **all = count ? malloc(count * sizeof *all) : NULL;
    if (all)
        for (mim__vs_t *v = sv->sessions; v; v = v->next)
            if (!v->removed)
                all[(*n)++] = v, v->refs++;
    pthread_mutex_unlock(&sv->sessions_lock);
    return all;
}

void mim__sessions_release_all(mim__vs_t **v, size_t n)
{
    for (size_t i = 0; i < n; i++)
        mim__vs_release(v[i]);
    free(v);
}

/* A session of pipeline s (owned: closed with it) for spec, its loop
 * started when it has a vest; not on the list yet. */
static int vs_open(mim__vs_t **out, mim_serve_t *sv, const mim_serve_session_spec_t *spec, mim_session_t *s,
                   int owned, mim_error_t *err)
{
    *out = NULL;
    mim__vs_t *vs = calloc(1, sizeof *vs);
    if (!vs) {
        if (owned)
            mim_session_close(&s);
        return mim_error_set(err, MIM_ENOMEM, "out of memory for session %s", spec->name);
    }
    snprintf(vs->name, sizeof vs->name, "%s", spec->name);
    vs->sv = sv;
    vs->s = s, vs->owned = owned;
    vs->spec = *spec;
    vs->mesh = mim_session_mesh(s);
    vs->out_mesh = mim_session_output_mesh(s);
    vs->map = mim_session_map(s);
    vs->t_start = mim_now();
    vs->refs = 1; /* the list's */
    mim__metrics_init(&vs->m);
    pthread_mutex_init(&vs->lock, NULL);
    int rc = 0;
    if (spec->vest[0]) {
        mim_serve_options_t o = sv->opt;
        o.vest = vs->spec.vest;
        o.key_rate = spec->key_rate > 0.0 ? spec->key_rate : sv->opt.key_rate;
        rc = mim__loop_open(&vs->loop, vs, &o, err);
    }
    if (rc) {
        vs_free(vs);
        return rc;
    }
    *out = vs;
    return 0;
}

/* Puts vs last on the list, unless its name was taken meanwhile. */
static int vs_insert(mim_serve_t *sv, mim__vs_t *vs, mim_error_t *err)
{
    pthread_mutex_lock(&sv->sessions_lock);
    int taken = find_live(sv, vs->name) != NULL;
    if (!taken) {
        mim__vs_t **p = &sv->sessions;
        while (*p)
            p = &(*p)->next;
        *p = vs;
    }
    pthread_mutex_unlock(&sv->sessions_lock);
    if (taken)
        return mim_error_set(err, -EEXIST, "session %s: already a session of that name", vs->name);
    return 0;
}

int mim__sessions_open_default(mim_serve_t *sv, const mim_serve_options_t *opt, mim_error_t *err)
{
    mim_serve_session_spec_t spec = {.key_rate = opt->key_rate};
    snprintf(spec.name, sizeof spec.name, "%s", MIM_SERVE_DEFAULT_SESSION);
    snprintf(spec.avatar, sizeof spec.avatar, "%s", mim_session_avatar(sv->s));
    if (opt->vest && snprintf(spec.vest, sizeof spec.vest, "%s", opt->vest) >= (int)sizeof spec.vest)
        return mim_error_set(err, MIM_EINVAL, "--vest: the spec is over %zu bytes", sizeof spec.vest - 1);
    mim__vs_t *vs = NULL;
    int rc = vs_open(&vs, sv, &spec, sv->s, 0, err);
    if (!rc && (rc = vs_insert(sv, vs, err)))
        vs_free(vs);
    return rc;
}

int mim_serve_session_add(mim_serve_t *sv, const mim_serve_session_spec_t *spec, mim_error_t *err)
{
    if (!mim__session_name_ok(spec->name))
        return bad_name(spec->name, err);
    if (!spec->avatar[0])
        return mim_error_set(err, MIM_EINVAL, "session %s: give an avatar (a mesh file or a template id)", spec->name);
    pthread_mutex_lock(&sv->sessions_lock);
    int taken = find_live(sv, spec->name) != NULL;
    unsigned live = 0;
    for (mim__vs_t *v = sv->sessions; v; v = v->next)
        live += !v->removed;
    pthread_mutex_unlock(&sv->sessions_lock);
    if (taken) /* before the avatar's seconds of work; vs_insert checks again */
        return mim_error_set(err, -EEXIST, "session %s: already a session of that name", spec->name);
    if (live >= MIM_SERVE_MAX_SESSIONS) /* each holds an avatar, its factor and a thread */
        return mim_error_set(err, -ENOSPC, "session %s: the service has its %d sessions; remove one first",
                             spec->name, MIM_SERVE_MAX_SESSIONS);
    mim_session_t *s = NULL;
    mim_error_t e = {0};
    int rc = mim_session_fork(&s, sv->s, NULL, &e);
    if (!rc)
        rc = mim_session_load_avatar(s, spec->avatar, &e);
    if (rc) {
        mim_session_close(&s);
        return mim_error_set(err, rc, "session %s: %s", spec->name, mim_error_text(&e));
    }
    mim__vs_t *vs = NULL;
    if ((rc = vs_open(&vs, sv, spec, s, 1, &e)))
        return mim_error_set(err, rc, "session %s: %s", spec->name, mim_error_text(&e));
    if ((rc = vs_insert(sv, vs, err)))
        vs_free(vs);
    return rc;
}

/* Stops vs's loop (joined; status then shows no vest). */
static void vs_stop(mim__vs_t *vs)
{
    pthread_mutex_lock(&vs->lock);
    mim__loop_t *l = vs->loop;
    vs->loop = NULL;
    pthread_mutex_unlock(&vs->lock);
    mim__loop_close(&l);
}

int mim_serve_session_remove(mim_serve_t *sv, const char *name, mim_error_t *err)
{
    pthread_mutex_lock(&sv->sessions_lock);
    mim__vs_t *vs = name && name[0] ? find_live(sv, name) : NULL;
    if (vs)
        vs->removed = 1;
    pthread_mutex_unlock(&sv->sessions_lock);
    if (!vs) {
        char shown[80];
        mim__printable(name ? name : "", name ? strlen(name) : 0, shown, sizeof shown);
        return mim_error_set(err, MIM_ENOTFOUND, "session '%s': no such session", shown);
    }
    vs_stop(vs); /* no frame is published after this */
    mim__ws_drop_session(sv->ws, vs);
    mim__vs_release(vs); /* the list's reference */
    return 0;
}

void mim__sessions_stop_all(mim_serve_t *sv)
{
    size_t n = 0;
    mim__vs_t **all = mim__sessions_all(sv, &n);
    for (size_t i = 0; i < n; i++)
        vs_stop(all[i]);
    mim__sessions_release_all(all, n);
}

void mim__sessions_free_all(mim_serve_t *sv)
{
    for (;;) {
        pthread_mutex_lock(&sv->sessions_lock);
        mim__vs_t *vs = find_live(sv, NULL);
        if (vs)
            vs->removed = 1;
        pthread_mutex_unlock(&sv->sessions_lock);
        if (!vs)
            return;
        mim__vs_release(vs); /* every client and handler is gone by now: the last reference */
    }
}

json_t *mim__vs_status(mim__vs_t *vs)
{
    pthread_mutex_lock(&vs->lock);
    json_t *vest = mim__loop_status(vs->loop);
    pthread_mutex_unlock(&vs->lock);
    return json_pack("{s:s, s:s, s:i, s:i, s:f, s:I, s:I, s:I, s:I, s:o, s:o}", "name", vs->name, "avatar",
                     mim_session_avatar(vs->s), "vertices", (int)vs->out_mesh->n_vertices, "faces",
                     (int)vs->out_mesh->n_faces, "uptime_s", mim_now() - vs->t_start, "vest_frames",
                     (json_int_t)mim__metrics_get(&vs->m, MIM__C_VEST_FRAMES), "frames",
                     (json_int_t)mim__metrics_get(&vs->m, MIM__C_FRAMES), "key_frames",
                     (json_int_t)mim__metrics_get(&vs->m, MIM__C_KEY_FRAMES), "frames_dropped",
                     (json_int_t)mim__metrics_get(&vs->m, MIM__C_DROPS), "stream", mim__ws_status(vs->sv->ws, vs),
                     "vest", vest);
}
