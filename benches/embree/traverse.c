/*
 * traverse.c: single-thread Embree ray-rate baseline for Kiln's BVH benchmark.
 *
 * Reads a triangle soup and a list of rays (formats below), builds one Embree
 * scene, and measures how many rays per second one thread traces with
 * rtcIntersect1 (closest hit) and with rtcOccluded1 (any hit, shadow rays).
 * It also prints a checksum (hit count and the sum of hit distances) so the
 * hits can be compared with Kiln's on the same files.
 *
 * Usage: traverse MESH RAYS
 *
 * File formats (all little-endian):
 *   MESH: u32 ntri, then ntri * 9 f32: v0.xyz v1.xyz v2.xyz per triangle
 *   RAYS: u32 nray, then nray * 8 f32: ox oy oz dx dy dz tmin tmax
 *         (directions are unit length, so t is a distance)
 *
 * Output: one "key value" line per figure on stdout, in this order:
 *   embree_version, triangles, rays, build_s, closest_hits, closest_t_sum,
 *   closest_rays_per_s, occluded_rays_per_s, occluded_blocked.
 * Notes and warnings go to stderr, prefixed with "#".
 *
 * Optional environment variables:
 *   EMBREE_CONFIG  passed to rtcNewDevice (e.g. "threads=1" for a one-thread
 *                  build; tracing is always on the calling thread only).
 *   EMBREE_ROBUST  if set to 1, the scene gets RTC_SCENE_FLAG_ROBUST
 *                  (default: no scene flags, Embree's fast mode).
 *
 * Builds against Embree 3 (<embree3/rtcore.h>, -lembree3) or Embree 4
 * (<embree4/rtcore.h>, -lembree4); the 3 vs 4 call differences are handled
 * by the wrappers below.
 */

#define _POSIX_C_SOURCE 199309L /* clock_gettime */

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#if defined(__has_include)
#  if __has_include(<embree4/rtcore.h>)
#    include <embree4/rtcore.h>
#  else
#    include <embree3/rtcore.h>
#  endif
#else
#  include <embree3/rtcore.h>
#endif

/* Timed passes over all rays per query kind; the best (fastest) one counts. */
#define REPEATS 5

/* ------------------------------------------------------------------------ */
/* Small helpers                                                             */
/* ------------------------------------------------------------------------ */

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Print "traverse: error: ..." (printf-style) and exit with status 1. */
static void die(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "traverse: error: ");
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    exit(1);
}

/* Decode a little-endian u32 independent of host byte order. */
static uint32_t le_u32(const unsigned char *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

/* Decode a little-endian IEEE-754 f32. */
static float le_f32(const unsigned char *p)
{
    uint32_t u = le_u32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

/*
 * Read a file made of a u32 record count followed by count * floats_per_record
 * f32 values. Returns a malloc'd float array and stores the count in *count.
 * Any problem (missing file, short header, short body) is fatal and the
 * message names the file and what was expected. Extra trailing bytes only
 * produce a warning.
 */
static float *read_counted_f32(const char *path, const char *kind,
                               const char *what, unsigned floats_per_record,
                               uint32_t *count)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        die("cannot open %s file '%s': %s", kind, path, strerror(errno));

    unsigned char head[4];
    size_t got = fread(head, 1, 4, f);
    if (got != 4)
        die("%s file '%s': expected a 4-byte little-endian u32 count of %s, "
            "file has only %zu bytes", kind, path, what, got);
    uint32_t n = le_u32(head);

    /* Size of the body we expect, computed in 64 bits to avoid overflow. */
    uint64_t nfloats = (uint64_t)n * floats_per_record;
    uint64_t nbytes = nfloats * 4u;
    if (nbytes / 4u != nfloats || nbytes > (uint64_t)SIZE_MAX)
        die("%s file '%s': count of %s in header (%u) is too large", kind,
            path, what, n);

    unsigned char *raw = malloc(nbytes ? (size_t)nbytes : 1);
    float *out = malloc(nfloats ? (size_t)nfloats * sizeof(float) : 1);
    if (!raw || !out)
        die("%s file '%s': out of memory reading %u %s", kind, path, n, what);

    got = fread(raw, 1, (size_t)nbytes, f);
    if ((uint64_t)got != nbytes)
        die("%s file '%s': header says %u %s, needing %llu bytes of f32 data "
            "after the count (%u f32 each), but only %zu bytes follow",
            kind, path, n, what, (unsigned long long)nbytes, floats_per_record,
            got);
    if (fgetc(f) != EOF)
        fprintf(stderr, "# warning: %s file '%s' has extra bytes after %u %s, "
                "ignored\n", kind, path, n, what);
    fclose(f);

    for (uint64_t i = 0; i < nfloats; i++)
        out[i] = le_f32(raw + 4 * i);
    free(raw);
    *count = n;
    return out;
}

/* ------------------------------------------------------------------------ */
/* Embree 3 / 4 call wrappers                                                */
/* ------------------------------------------------------------------------ */

#if RTC_VERSION_MAJOR >= 4
static void closest_hit(RTCScene scene, struct RTCRayHit *rh)
{
    rtcIntersect1(scene, rh, NULL);
}
static void any_hit(RTCScene scene, struct RTCRay *r)
{
    rtcOccluded1(scene, r, NULL);
}
#else
static void closest_hit(RTCScene scene, struct RTCRayHit *rh)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx); /* incoherent rays, no filter */
    rtcIntersect1(scene, &ctx, rh);
}
static void any_hit(RTCScene scene, struct RTCRay *r)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rtcOccluded1(scene, &ctx, r);
}
#endif

/* Fill an Embree ray from record i of the ray array (8 floats per ray). */
static void load_ray(struct RTCRay *r, const float *rays, uint32_t i)
{
    const float *p = rays + 8 * (size_t)i;
    r->org_x = p[0];
    r->org_y = p[1];
    r->org_z = p[2];
    r->dir_x = p[3];
    r->dir_y = p[4];
    r->dir_z = p[5];
    r->tnear = p[6];
    r->tfar = p[7];
    r->time = 0.0f;
    r->mask = 0xFFFFFFFFu;
    r->id = i;
    r->flags = 0;
}

static void on_embree_error(void *user, enum RTCError code, const char *str)
{
    (void)user;
    fprintf(stderr, "traverse: embree error %d: %s\n", (int)code,
            str ? str : "(no message)");
    exit(1);
}

/* ------------------------------------------------------------------------ */
/* Main                                                                      */
/* ------------------------------------------------------------------------ */

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr,
                "usage: %s MESH RAYS\n"
                "  MESH: u32 ntri, then ntri*9 f32 (v0.xyz v1.xyz v2.xyz)\n"
                "  RAYS: u32 nray, then nray*8 f32 (ox oy oz dx dy dz tmin tmax)\n",
                argv[0]);
        return 2;
    }
    const char *mesh_path = argv[1];
    const char *ray_path = argv[2];

    uint32_t ntri = 0, nray = 0;
    float *tris = read_counted_f32(mesh_path, "mesh", "triangles", 9, &ntri);
    float *rays = read_counted_f32(ray_path, "rays", "rays", 8, &nray);
    if ((uint64_t)ntri * 3u > 0xFFFFFFFFu)
        die("mesh file '%s': too many triangles (%u) for 32-bit vertex indices",
            mesh_path, ntri);

    /* Warn (do not fail) if directions are not unit length: the t sum is only
     * comparable between renderers when t is a distance. */
    uint32_t nonunit = 0;
    for (uint32_t i = 0; i < nray; i++) {
        const float *d = rays + 8 * (size_t)i + 3;
        double len2 = (double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2];
        if (fabs(len2 - 1.0) > 1e-4)
            nonunit++;
    }
    if (nonunit)
        fprintf(stderr, "# warning: %u of %u ray directions are not unit length\n",
                nonunit, nray);

    /* ---- Device ---- */
    const char *config = getenv("EMBREE_CONFIG");
    RTCDevice device = rtcNewDevice(config);
    if (!device) {
        fprintf(stderr, "traverse: rtcNewDevice(%s) failed (error %d)\n",
                config ? config : "NULL", (int)rtcGetDeviceError(NULL));
        return 1;
    }
    rtcSetDeviceErrorFunction(device, on_embree_error, NULL);

    printf("embree_version %ld.%ld.%ld\n",
           (long)rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION_MAJOR),
           (long)rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION_MINOR),
           (long)rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION_PATCH));
    fprintf(stderr, "# embree backface_culling %ld, tasking_system %ld (0 internal, 1 TBB, 2 PPL)\n",
            (long)rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED),
            (long)rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_TASKING_SYSTEM));
    printf("triangles %u\n", ntri);
    printf("rays %u\n", nray);

    /* ---- Scene: one triangle geometry, unshared vertices ----
     * The soup is uploaded as 3*ntri vertices and index triple (3i, 3i+1, 3i+2)
     * for triangle i. Buffer creation and copying are outside the build timer;
     * build_s covers rtcCommitGeometry + rtcCommitScene (the BVH build). */
    const char *robust_env = getenv("EMBREE_ROBUST");
    int robust = robust_env && strcmp(robust_env, "1") == 0;
    RTCScene scene = rtcNewScene(device);
    rtcSetSceneFlags(scene, robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    fprintf(stderr, "# scene flags: %s, build quality: high\n",
            robust ? "ROBUST" : "none");

    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_HIGH);
    /* rtcSetNewGeometryBuffer pads the buffer as Embree requires. */
    float *vb = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0,
                                        RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                        (size_t)ntri * 3);
    unsigned *ib = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0,
                                           RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                           (size_t)ntri);
    if (ntri > 0) {
        memcpy(vb, tris, (size_t)ntri * 9 * sizeof(float));
        for (uint32_t i = 0; i < 3 * ntri; i++)
            ib[i] = i;
    }
    free(tris);

    double t0 = now_s();
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom);
    rtcCommitScene(scene);
    double build_s = now_s() - t0;
    printf("build_s %.6f\n", build_s);

    /* ---- Closest hit: rtcIntersect1, one thread ----
     * Each pass fills the RTCRayHit from the ray array and traces it, as a
     * renderer would. The checksum comes from the first pass; later passes
     * must agree exactly (Embree is deterministic), which is checked. */
    double best_closest = INFINITY;
    uint64_t hits = 0;
    double t_sum = 0.0;
    for (int rep = 0; rep < REPEATS; rep++) {
        uint64_t h = 0;
        double s = 0.0;
        double start = now_s();
        for (uint32_t i = 0; i < nray; i++) {
            struct RTCRayHit rh;
            load_ray(&rh.ray, rays, i);
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
            closest_hit(scene, &rh);
            if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
                h++;
                s += (double)rh.ray.tfar; /* tfar is set to the hit distance */
            }
        }
        double el = now_s() - start;
        if (el < best_closest)
            best_closest = el;
        if (rep == 0) {
            hits = h;
            t_sum = s;
        } else if (h != hits || s != t_sum) {
            fprintf(stderr, "# warning: closest-hit pass %d differs from pass 0\n", rep);
        }
    }
    printf("closest_hits %llu\n", (unsigned long long)hits);
    printf("closest_t_sum %.17g\n", t_sum);
    printf("closest_rays_per_s %.0f\n", best_closest > 0 ? nray / best_closest : 0.0);

    /* ---- Any hit: rtcOccluded1, one thread ----
     * Same rays and [tmin, tmax]; Embree sets tfar to -inf when the ray is
     * blocked. */
    double best_occ = INFINITY;
    uint64_t blocked = 0;
    for (int rep = 0; rep < REPEATS; rep++) {
        uint64_t b = 0;
        double start = now_s();
        for (uint32_t i = 0; i < nray; i++) {
            struct RTCRay r;
            load_ray(&r, rays, i);
            any_hit(scene, &r);
            if (r.tfar == -INFINITY)
                b++;
        }
        double el = now_s() - start;
        if (el < best_occ)
            best_occ = el;
        if (rep == 0)
            blocked = b;
        else if (b != blocked)
            fprintf(stderr, "# warning: occluded pass %d differs from pass 0\n", rep);
    }
    printf("occluded_rays_per_s %.0f\n", best_occ > 0 ? nray / best_occ : 0.0);
    printf("occluded_blocked %llu\n", (unsigned long long)blocked);

    if (blocked != hits)
        fprintf(stderr, "# note: occluded_blocked (%llu) != closest_hits (%llu)\n",
                (unsigned long long)blocked, (unsigned long long)hits);

    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
    free(rays);
    return 0;
}
