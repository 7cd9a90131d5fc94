/* Embree 3 (Debian's libembree-dev) timed on exactly the rays our tracer
 * traces, as embree_same_rays.py does for Embree 4 through embreex, but in C
 * so that the device configuration can be chosen (node width, triangle
 * layout, instruction set).
 *
 * `target/release/examples/ray_throughput --dump DIR` writes the triangles
 * and both ray sets (little-endian f32 rows); this program builds one Embree
 * scene from a stem's triangles and traces each set with rtcIntersect1 /
 * rtcOccluded1, one ray per call, for at least 3 CPU-seconds of the calling
 * thread, and prints rays per CPU-second and the hit fraction (which must
 * agree with ray_throughput's).
 *
 * Measurement only, never part of the build:
 *   apt-get install libembree-dev
 *   cc -O2 docs/validation/embree3_same_rays.c -o /tmp/embree3_same_rays -lembree3 -lm
 *   /tmp/embree3_same_rays DIR mesh [QUALITY [DEVICE_CONFIG]]
 * QUALITY is RTC_BUILD_QUALITY (0 low, 1 medium: Embree's default, 2 high);
 * DEVICE_CONFIG e.g. "threads=1,tri_accel=bvh4.triangle4,isa=sse4.2".
 */
#include <embree3/rtcore.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static float *load(const char *path, size_t *rows, size_t width) {
  FILE *f = fopen(path, "rb");
  if (!f) { perror(path); exit(1); }
  fseek(f, 0, SEEK_END);
  long size = ftell(f);
  fseek(f, 0, SEEK_SET);
  float *data = malloc(size);
  if (fread(data, 1, size, f) != (size_t)size) { perror(path); exit(1); }
  fclose(f);
  *rows = size / sizeof(float) / width;
  return data;
}

static double thread_cpu_seconds(void) {
  struct timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec + t.tv_nsec * 1e-9;
}

int main(int argc, char **argv) {
  if (argc < 3) { fprintf(stderr, "usage: %s DIR STEM [QUALITY [CONFIG]]\n", argv[0]); return 2; }
  const char *dir = argv[1], *stem = argv[2];
  int quality = argc > 3 ? atoi(argv[3]) : RTC_BUILD_QUALITY_MEDIUM;
  const char *config = argc > 4 ? argv[4] : "threads=1";
  char path[4096];
  size_t triangles, rays;
  snprintf(path, sizeof path, "%s/%s.triangles.f32", dir, stem);
  float *t = load(path, &triangles, 9);

  RTCDevice device = rtcNewDevice(config);
  RTCScene scene = rtcNewScene(device);
  rtcSetSceneBuildQuality(scene, quality);
  RTCGeometry mesh = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  float *v = rtcSetNewGeometryBuffer(mesh, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, 3 * triangles);
  unsigned *index = rtcSetNewGeometryBuffer(mesh, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, triangles);
  for (size_t i = 0; i < 9 * triangles; i++) v[i] = t[i];
  for (size_t i = 0; i < 3 * triangles; i++) index[i] = (unsigned)i;
  rtcCommitGeometry(mesh);
  rtcAttachGeometry(scene, mesh);
  rtcReleaseGeometry(mesh);
  rtcCommitScene(scene);

  const char *kinds[2] = {"closest", "shadow"};
  for (int k = 0; k < 2; k++) {
    snprintf(path, sizeof path, "%s/%s.%s.f32", dir, stem, kinds[k]);
    float *r = load(path, &rays, 7);
    struct RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    size_t traced = 0, hits = 0;
    double start = thread_cpu_seconds();
    while (thread_cpu_seconds() - start < 3.0) {
      for (size_t i = 0; i < rays; i++) {
        const float *q = r + 7 * i;
        struct RTCRayHit rh;
        rh.ray.org_x = q[0]; rh.ray.org_y = q[1]; rh.ray.org_z = q[2];
        rh.ray.dir_x = q[3]; rh.ray.dir_y = q[4]; rh.ray.dir_z = q[5];
        rh.ray.tnear = 0.0f;
        rh.ray.tfar = q[6];
        rh.ray.mask = ~0u; rh.ray.flags = 0; rh.ray.time = 0.0f;
        if (k == 0) {
          rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
          rtcIntersect1(scene, &context, &rh);
          hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
        } else {
          rtcOccluded1(scene, &context, &rh.ray);
          hits += rh.ray.tfar < 0.0f;
        }
      }
      traced += rays;
    }
    double cpu = thread_cpu_seconds() - start;
    printf("%s %s: %.2f M rays per CPU-second, hit fraction %.3f (Embree 3, %zu triangles)\n", stem, kinds[k],
           traced / cpu / 1e6, (double)hits / traced, triangles);
    free(r);
  }
  rtcReleaseScene(scene);
  rtcReleaseDevice(device);
  free(t);
  return 0;
}
