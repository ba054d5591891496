/* A brick's program writing the tacho-motor attributes the way ev3dev-lang-cpp does: every write
 * opens the attribute as a std::ofstream would (O_WRONLY | O_CREAT | O_TRUNC), writes the value and
 * closes it; every read opens, reads and closes. Both of model A's wheels (outB, outC) turn
 * argv[1] degrees at argv[2] degrees per second with run-to-rel-pos; the program waits for both
 * to leave the `running` state and prints their positions.
 * ev3dev-lang-cpp itself is not packaged in Debian, so this program stands in for it.
 * Exit status: 0, 1 on an error (printed). */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define CLASS "/sys/class/tacho-motor"

static int attr_write(const char *dev, const char *attr, const char *value) {
  char path[1024];
  snprintf(path, sizeof path, "%s/%s", dev, attr);
  int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0666);
  if (fd < 0) {
    fprintf(stderr, "open %s: %s\n", path, strerror(errno));
    return -1;
  }
  ssize_t n = write(fd, value, strlen(value));
  int err = n < 0 ? errno : 0;
  close(fd);
  if (n < 0) {
    fprintf(stderr, "write %s <- %s: %s\n", path, value, strerror(err));
    return -1;
  }
  return 0;
}

static int attr_read(const char *dev, const char *attr, char *out, size_t size) {
  char path[1024];
  snprintf(path, sizeof path, "%s/%s", dev, attr);
  int fd = open(path, O_RDONLY);
  if (fd < 0) {
    fprintf(stderr, "open %s: %s\n", path, strerror(errno));
    return -1;
  }
  ssize_t n = read(fd, out, size - 1);
  close(fd);
  if (n < 0) {
    fprintf(stderr, "read %s: %s\n", path, strerror(errno));
    return -1;
  }
  out[n] = '\0';
  if (n > 0 && out[n - 1] == '\n') out[n - 1] = '\0';
  return 0;
}

/* The class directory of the motor whose address is ev3-ports:<port>, into dev. */
static int find_motor(const char *port, char *dev, size_t size) {
  DIR *d = opendir(CLASS);
  if (!d) {
    fprintf(stderr, "opendir %s: %s\n", CLASS, strerror(errno));
    return -1;
  }
  char want[64], have[64];
  snprintf(want, sizeof want, "ev3-ports:%s", port);
  struct dirent *e;
  int found = -1;
  while (found < 0 && (e = readdir(d)) != NULL) {
    if (e->d_name[0] == '.') continue;
    snprintf(dev, size, "%s/%s", CLASS, e->d_name);
    if (attr_read(dev, "address", have, sizeof have) == 0 && strcmp(have, want) == 0) found = 0;
  }
  closedir(d);
  if (found < 0) fprintf(stderr, "no motor on %s\n", port);
  return found;
}

int main(int argc, char **argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: %s DEGREES SPEED\n", argv[0]);
    return 1;
  }
  char left[512], right[512];
  if (find_motor("outB", left, sizeof left) || find_motor("outC", right, sizeof right)) return 1;
  const char *devs[2] = {left, right};
  for (int i = 0; i < 2; ++i)
    if (attr_write(devs[i], "speed_sp", argv[2]) || attr_write(devs[i], "position_sp", argv[1]) ||
        attr_write(devs[i], "stop_action", "hold"))
      return 1;
  for (int i = 0; i < 2; ++i)
    if (attr_write(devs[i], "command", "run-to-rel-pos")) return 1;
  for (int running = 1; running;) {
    running = 0;
    for (int i = 0; i < 2; ++i) {
      char state[128];
      if (attr_read(devs[i], "state", state, sizeof state)) return 1;
      if (strstr(state, "running")) running = 1;
    }
    struct timespec ts = {0, 10 * 1000 * 1000};
    nanosleep(&ts, NULL);
  }
  char pl[64], pr[64];
  if (attr_read(left, "position", pl, sizeof pl) || attr_read(right, "position", pr, sizeof pr)) return 1;
  printf("%s %s\n", pl, pr);
  return 0;
}
