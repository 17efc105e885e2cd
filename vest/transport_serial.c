/* Serial transport: the PrioVR dongle and wired sensors are USB CDC serial
 * ports (vendor 0x2476), 115200 baud, 8N1, raw bytes. */
#include "transport_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

int mim__serial_open(mim_vest_transport_t *t, mim_error_t *err)
{
    int fd = open(t->path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        int e = errno;
        if (e == ENOENT || e == ENODEV || e == ENXIO || e == EIO)
            return mim_error_set(err, -e, "%s: no such device (is the vest plugged in?)", t->desc);
        if (e == EACCES)
            return mim_error_set(err, -e, "%s: permission denied (join the dialout group)", t->desc);
        return mim_error_set(err, -e, "%s: %s", t->desc, strerror(e));
    }
    struct termios tio;
    if (tcgetattr(fd, &tio)) {
        int e = errno;
        close(fd);
        return mim_error_set(err, -e, "%s: not a serial port (%s)", t->desc, strerror(e));
    }
    cfmakeraw(&tio);
    tio.c_cflag &= ~(tcflag_t)(PARENB | CSTOPB | CSIZE | CRTSCTS);
    tio.c_cflag |= CS8 | CLOCAL | CREAD;
    tio.c_cc[VMIN] = 0, tio.c_cc[VTIME] = 0;
    cfsetispeed(&tio, B115200);
    cfsetospeed(&tio, B115200);
    if (tcsetattr(fd, TCSANOW, &tio)) {
        int e = errno;
        close(fd);
        return mim_error_set(err, -e, "%s: cannot set 115200 8N1 raw (%s)", t->desc, strerror(e));
    }
    t->fd = fd;
    return 0;
}

int mim__serial_read(mim_vest_transport_t *t, uint8_t *buf, size_t cap, int ms, mim_error_t *err)
{
    struct pollfd p = {t->fd, POLLIN, 0};
    int r = poll(&p, 1, ms);
    if (r < 0) return errno == EINTR ? 0 : mim_error_set(err, -errno, "%s: poll: %s", t->desc, strerror(errno));
    if (r == 0) return 0;
    ssize_t n = read(t->fd, buf, cap);
    if (n > 0) return (int)n;
    if (n < 0 && (errno == EAGAIN || errno == EINTR)) return 0;
    if (n == 0 || errno == EIO || errno == ENODEV || errno == ENXIO)
        return mim_error_set(err, -ENODEV, "%s: disconnected", t->desc);
    return mim_error_set(err, -errno, "%s: read error: %s", t->desc, strerror(errno));
}

int mim__serial_write(mim_vest_transport_t *t, const uint8_t *buf, size_t n, mim_error_t *err)
{
    size_t done = 0;
    while (done < n) {
        ssize_t w = write(t->fd, buf + done, n - done);
        if (w < 0) {
            if (errno == EINTR) continue;
            if (errno == EAGAIN) {
                struct pollfd p = {t->fd, POLLOUT, 0};
                if (poll(&p, 1, t->o.timeout_ms) <= 0)
                    return mim_error_set(err, -ETIMEDOUT, "%s: write timed out", t->desc);
                continue;
            }
            return mim_error_set(err, -errno, "%s: write error: %s", t->desc, strerror(errno));
        }
        done += (size_t)w;
    }
    return 0;
}

void mim__serial_close(mim_vest_transport_t *t)
{
    if (t->fd >= 0) close(t->fd);
    t->fd = -1;
}
