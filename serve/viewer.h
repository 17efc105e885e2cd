/* serve/viewer.c: the web viewer's files (serve/viewer/ and three.js from
 * node_modules), embedded into the binary at build time. */
#ifndef MIM_SERVE_VIEWER_H
#define MIM_SERVE_VIEWER_H

struct mg_connection;

/* Answers a GET (or HEAD) of one of the viewer's paths: "/", "/index.html",
 * "/viewer.js", "/viewer.css", "/three/three.module.js",
 * "/three/three.core.js" and "/three/addons/controls/OrbitControls.js".
 * Returns the HTTP status sent (200), or 0, having sent nothing, when path
 * is none of them (the caller then answers 404). */
int mim__viewer_serve(struct mg_connection *c, const char *path);

#endif
