/* libFuzzer harness: a WebSocket client's text message to mimic serve's
 * /ws stream (schemas/serve-ws-frame.md). It must give a format or a reason
 * that is one line and valid UTF-8, since the reason goes back to the
 * client inside a JSON error message. */
#include "internal.h"

#include <jansson.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char why[256];
    int fmt = mim__ws_parse_message((const char *)data, size, why, sizeof why);
    if (fmt > 1 || fmt < -1)
        abort();
    if (fmt < 0) {
        json_t *s = json_string(why); /* NULL when why is not UTF-8 */
        if (!why[0] || strchr(why, '\n') || !s)
            abort();
        json_decref(s);
    }
    return 0;
}
