/* Devices that look like vests: USB serial ports of YOST Labs' vendor id
 * (0x2476), found through sysfs, and HID devices of that vendor through
 * hidapi. */
#include "mim_vest_protocol.h"
#include "mim_vest_transport.h"

#include <dirent.h>
#include <hidapi/hidapi.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <wchar.h>

static int read_line(const char *path, char *out, size_t n)
{
    FILE *f = fopen(path, "r");
    if (!f) return -1;
    if (!fgets(out, (int)n, f)) out[0] = 0;
    fclose(f);
    out[strcspn(out, "\r\n")] = 0;
    return 0;
}

static int by_name(const struct dirent **a, const struct dirent **b) { return strcmp((*a)->d_name, (*b)->d_name); }

int mim_vest_list(mim_vest_device_t *out, int max, const char *sysfs_root, int list_hid, mim_error_t *err)
{
    (void)err;
    if (!sysfs_root) sysfs_root = "/sys";
    int found = 0;
    char dir[PATH_MAX];
    snprintf(dir, sizeof dir, "%s/class/tty", sysfs_root);
    struct dirent **ents = NULL;
    int n = scandir(dir, &ents, NULL, by_name);
    for (int i = 0; i < n; i++) {
        const char *name = ents[i]->d_name;
        if (strncmp(name, "ttyACM", 6) && strncmp(name, "ttyUSB", 6)) continue;
        /* the USB device holding idVendor is the tty's device or one of its parents */
        char dev[PATH_MAX + 300], real[PATH_MAX];
        snprintf(dev, sizeof dev, "%s/%s/device", dir, name);
        if (!realpath(dev, real)) continue;
        for (int up = 0; up < 4; up++) {
            char f[PATH_MAX + 16], v[64] = "", prod[128] = "";
            snprintf(f, sizeof f, "%s/idVendor", real);
            if (!read_line(f, v, sizeof v)) {
                if (strtoul(v, NULL, 16) == MIM_VEST_VENDOR_ID && found < max) {
                    snprintf(f, sizeof f, "%s/product", real);
                    read_line(f, prod, sizeof prod);
                    snprintf(out[found].spec, sizeof out[found].spec, "serial:/dev/%s", name);
                    snprintf(out[found].what, sizeof out[found].what, "%s", prod[0] ? prod : "USB serial, vendor 2476");
                    found++;
                }
                break;
            }
            char *slash = strrchr(real, '/');
            if (!slash || slash == real) break;
            *slash = 0;
        }
    }
    for (int i = 0; i < n; i++) free(ents[i]);
    free(ents);
    if (list_hid && hid_init() == 0) {
        struct hid_device_info *all = hid_enumerate(MIM_VEST_VENDOR_ID, 0);
        for (struct hid_device_info *d = all; d && found < max; d = d->next) {
            char serial[128] = "", prod[128] = "";
            if (d->serial_number) wcstombs(serial, d->serial_number, sizeof serial - 1);
            if (d->product_string) wcstombs(prod, d->product_string, sizeof prod - 1);
            serial[sizeof serial - 1] = prod[sizeof prod - 1] = 0;
            snprintf(out[found].spec, sizeof out[found].spec, "hid:%04x:%04x%s%s", d->vendor_id, d->product_id,
                     serial[0] ? ":" : "", serial);
            snprintf(out[found].what, sizeof out[found].what, "%s (%s)", prod[0] ? prod : "HID device", d->path);
            found++;
        }
        hid_free_enumeration(all);
        hid_exit();
    }
    return found;
}
