/* The web viewer's files, embedded into the binary by the assembler's
 * .incbin at build time (serve/CMakeLists.txt passes their absolute paths),
 * so `mimic serve` needs nothing beside it at run time: serve/viewer/ (the
 * page) and three.js from node_modules (npm ci; a placeholder module when it
 * was missing at configure time, and the page then says so), with the
 * addons the page imports (OrbitControls, GLTFLoader and what it imports). */
#include "internal.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>

#if !defined(MIM_VIEWER_INDEX_HTML) || !defined(MIM_VIEWER_JS) || !defined(MIM_VIEWER_CSS) ||              \
    !defined(MIM_VIEWER_THREE_MODULE) || !defined(MIM_VIEWER_THREE_CORE) || !defined(MIM_VIEWER_ORBIT) ||             \
    !defined(MIM_VIEWER_GLTF) || !defined(MIM_VIEWER_BGU) || !defined(MIM_VIEWER_SKELETON)
#error "serve/CMakeLists.txt passes the viewer's file paths (MIM_VIEWER_*)"
#endif

/* MIM__INCBIN(sym, "path") defines, in .rodata, the bytes of the file as
 * sym[] and their count as the uint64 sym_len (a NUL follows the bytes but
 * is not counted). Hidden, so the references stay PC-relative. */
#define MIM__INCBIN(sym, file)                                                                             \
    __asm__(".pushsection .rodata\n"                                                                       \
            ".balign 16\n"                                                                                 \
            ".globl " #sym "\n"                                                                            \
            ".hidden " #sym "\n" #sym ":\n"                                                                \
            ".incbin \"" file "\"\n" #sym "_end:\n"                                                        \
            ".byte 0\n"                                                                                    \
            ".balign 8\n"                                                                                  \
            ".globl " #sym "_len\n"                                                                        \
            ".hidden " #sym "_len\n" #sym "_len:\n"                                                        \
            ".quad " #sym "_end - " #sym "\n"                                                              \
            ".popsection\n");                                                                              \
    extern const unsigned char sym[] __attribute__((visibility("hidden")));                                \
    extern const uint64_t sym##_len __attribute__((visibility("hidden")))

MIM__INCBIN(mim__va_index_html, MIM_VIEWER_INDEX_HTML);
MIM__INCBIN(mim__va_viewer_js, MIM_VIEWER_JS);
MIM__INCBIN(mim__va_viewer_css, MIM_VIEWER_CSS);
MIM__INCBIN(mim__va_three_module, MIM_VIEWER_THREE_MODULE);
MIM__INCBIN(mim__va_three_core, MIM_VIEWER_THREE_CORE);
MIM__INCBIN(mim__va_orbit, MIM_VIEWER_ORBIT);
MIM__INCBIN(mim__va_gltf, MIM_VIEWER_GLTF);
MIM__INCBIN(mim__va_bgu, MIM_VIEWER_BGU);
MIM__INCBIN(mim__va_skeleton, MIM_VIEWER_SKELETON);

#define HTML "text/html; charset=utf-8"
#define JS "text/javascript"
#define CSS "text/css"

static const struct asset {
    const char *path, *type;
    const unsigned char *data;
    const uint64_t *len;
} assets[] = {
    {"/", HTML, mim__va_index_html, &mim__va_index_html_len},
    {"/index.html", HTML, mim__va_index_html, &mim__va_index_html_len},
    {"/viewer.js", JS, mim__va_viewer_js, &mim__va_viewer_js_len},
    {"/viewer.css", CSS, mim__va_viewer_css, &mim__va_viewer_css_len},
    /* index.html's import map: "three" is three.module.js, which imports
     * ./three.core.js; the addons import "three". */
    {"/three/three.module.js", JS, mim__va_three_module, &mim__va_three_module_len},
    {"/three/three.core.js", JS, mim__va_three_core, &mim__va_three_core_len},
    {"/three/addons/controls/OrbitControls.js", JS, mim__va_orbit, &mim__va_orbit_len},
    /* the avatar's look (GET /api/avatar.glb); GLTFLoader imports ../utils/ */
    {"/three/addons/loaders/GLTFLoader.js", JS, mim__va_gltf, &mim__va_gltf_len},
    {"/three/addons/utils/BufferGeometryUtils.js", JS, mim__va_bgu, &mim__va_bgu_len},
    {"/three/addons/utils/SkeletonUtils.js", JS, mim__va_skeleton, &mim__va_skeleton_len},
};

int mim__viewer_reply(const char *path, mim__reply_t *rp)
{
    for (size_t i = 0; path && i < sizeof assets / sizeof assets[0]; i++) {
        const struct asset *a = &assets[i];
        if (strcmp(a->path, path))
            continue;
        rp->status = 200;
        rp->type = a->type;
        rp->fixed = a->data;
        rp->len = (size_t)*a->len;
        rp->cache = "no-cache"; /* revalidate every time: a rebuilt binary serves new files */
        return 200;
    }
    return 0;
}
