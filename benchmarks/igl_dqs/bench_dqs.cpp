// Time libigl's own C++ dual-quaternion skinning, igl::dqs, on a rig written by
// benchmarks/skinning_vs_igl.py. This file is ours; libigl and Eigen are
// header-only and are found at build time, never copied into this repository.
//
// Build (skinning_vs_igl.py does this, caching the binary under ~/.cache/stbs/igl_dqs/):
//   g++ -O3 -march=native -DNDEBUG -std=c++17 -pthread \
//       -I$EIGEN_INCLUDE -I$LIBIGL_INCLUDE bench_dqs.cpp -o bench_dqs
//
// igl::dqs parallelises over vertices with igl::parallel_for (std::thread, one
// thread per hardware thread or IGL_NUM_THREADS; no OpenMP), so no -fopenmp.
//
// Usage: bench_dqs RIG.bin [--repeats R] [--float] [--out U.bin]
//
// RIG.bin (little endian): 8-byte magic "STBSDQS1"; int64 n, b, k;
// float64 V[n*3]; int32 idx[n*k]; float64 w[n*k]; float64 Q[b*4] (w, x, y, z);
// float64 T[b*3]. The top-k weights (idx, w) are scattered into the dense
// #V by #C weight matrix that igl::dqs reads (column-major Eigen::MatrixX, as in
// libigl's own explicit instantiation and tutorial).
//
// Prints one JSON object on stdout. --out writes U (n*3 float64, row-major).

#include <igl/default_num_threads.h>
#include <igl/dqs.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace
{
[[noreturn]] void die(const std::string & msg)
{
  std::fprintf(stderr, "bench_dqs: %s\n", msg.c_str());
  std::exit(2);
}

template <typename X>
void read_into(std::FILE * f, X * dst, size_t count, const char * what)
{
  if (std::fread(dst, sizeof(X), count, f) != count)
  {
    die(std::string("truncated input while reading ") + what);
  }
}

struct Rig
{
  int64_t n = 0, b = 0, k = 0;
  std::vector<double> V, w, Q, T;
  std::vector<int32_t> idx;
};

Rig read_rig(const char * path)
{
  std::FILE * f = std::fopen(path, "rb");
  if (!f) die(std::string("cannot open ") + path);
  char magic[8];
  read_into(f, magic, 8, "magic");
  if (std::memcmp(magic, "STBSDQS1", 8) != 0) die("not a STBSDQS1 file");
  Rig r;
  int64_t head[3];
  read_into(f, head, 3, "header");
  r.n = head[0];
  r.b = head[1];
  r.k = head[2];
  if (r.n <= 0 || r.b <= 0 || r.k <= 0 || r.k > r.b) die("bad header");
  r.V.resize(r.n * 3);
  r.idx.resize(r.n * r.k);
  r.w.resize(r.n * r.k);
  r.Q.resize(r.b * 4);
  r.T.resize(r.b * 3);
  read_into(f, r.V.data(), r.V.size(), "V");
  read_into(f, r.idx.data(), r.idx.size(), "idx");
  read_into(f, r.w.data(), r.w.size(), "w");
  read_into(f, r.Q.data(), r.Q.size(), "Q");
  read_into(f, r.T.data(), r.T.size(), "T");
  std::fclose(f);
  for (int32_t i : r.idx)
  {
    if (i < 0 || i >= r.b) die("bone index out of range");
  }
  return r;
}

template <typename S>
int run(const Rig & r, int repeats, const char * out_path)
{
  using MatX = Eigen::Matrix<S, Eigen::Dynamic, Eigen::Dynamic>;
  using Quat = Eigen::Quaternion<S>;
  using Vec3 = Eigen::Matrix<S, 3, 1>;
  MatX V(r.n, 3), W = MatX::Zero(r.n, r.b), U;
  for (int64_t i = 0; i < r.n; i++)
  {
    for (int c = 0; c < 3; c++) V(i, c) = S(r.V[i * 3 + c]);
    for (int64_t j = 0; j < r.k; j++) W(i, r.idx[i * r.k + j]) += S(r.w[i * r.k + j]);
  }
  std::vector<Quat, Eigen::aligned_allocator<Quat>> vQ(r.b);
  std::vector<Vec3> vT(r.b);
  for (int64_t c = 0; c < r.b; c++)
  {
    vQ[c] = Quat(S(r.Q[c * 4]), S(r.Q[c * 4 + 1]), S(r.Q[c * 4 + 2]), S(r.Q[c * 4 + 3]));
    vT[c] = Vec3(S(r.T[c * 3]), S(r.T[c * 3 + 1]), S(r.T[c * 3 + 2]));
  }

  igl::dqs(V, W, vQ, vT, U);  // warm-up: allocates U, faults pages in
  std::vector<double> ns(repeats);
  for (int t = 0; t < repeats; t++)
  {
    const auto t0 = std::chrono::steady_clock::now();
    igl::dqs(V, W, vQ, vT, U);
    const auto t1 = std::chrono::steady_clock::now();
    ns[t] = std::chrono::duration<double, std::nano>(t1 - t0).count() / double(r.n);
  }
  std::vector<double> sorted = ns;
  std::sort(sorted.begin(), sorted.end());
  const double median = repeats % 2 ? sorted[repeats / 2]
                                    : 0.5 * (sorted[repeats / 2 - 1] + sorted[repeats / 2]);
  double checksum = 0;
  for (int64_t i = 0; i < r.n; i++) checksum += double(U(i, 0)) + double(U(i, 1)) + double(U(i, 2));

  if (out_path)
  {
    std::FILE * f = std::fopen(out_path, "wb");
    if (!f) die(std::string("cannot write ") + out_path);
    std::vector<double> row(3);
    for (int64_t i = 0; i < r.n; i++)
    {
      for (int c = 0; c < 3; c++) row[c] = double(U(i, c));
      if (std::fwrite(row.data(), sizeof(double), 3, f) != 3) die("write failed");
    }
    std::fclose(f);
  }
  std::printf(
      "{\"n\": %lld, \"bones\": %lld, \"influences\": %lld, \"scalar\": \"%s\", "
      "\"threads\": %u, \"repeats\": %d, \"min_ns_per_vertex\": %.6g, "
      "\"median_ns_per_vertex\": %.6g, \"W_bytes\": %lld, \"checksum\": %.17g, "
      "\"eigen\": \"%d.%d.%d\", \"weights\": \"dense column-major #V by #C\"}\n",
      (long long)r.n, (long long)r.b, (long long)r.k, sizeof(S) == 8 ? "double" : "float",
      igl::default_num_threads(), repeats, sorted.front(), median,
      (long long)(W.size() * sizeof(S)), checksum, EIGEN_WORLD_VERSION, EIGEN_MAJOR_VERSION,
      EIGEN_MINOR_VERSION);
  return 0;
}
}  // namespace

int main(int argc, char * argv[])
{
  if (argc < 2) die("usage: bench_dqs RIG.bin [--repeats R] [--float] [--out U.bin]");
  int repeats = 10;
  bool single = false;
  const char * out_path = nullptr;
  for (int a = 2; a < argc; a++)
  {
    const std::string arg = argv[a];
    if (arg == "--repeats" && a + 1 < argc)
    {
      repeats = std::atoi(argv[++a]);
      if (repeats < 1) die("--repeats must be >= 1");
    }
    else if (arg == "--float")
    {
      single = true;
    }
    else if (arg == "--out" && a + 1 < argc)
    {
      out_path = argv[++a];
    }
    else
    {
      die("unknown argument " + arg);
    }
  }
  const Rig r = read_rig(argv[1]);
  return single ? run<float>(r, repeats, out_path) : run<double>(r, repeats, out_path);
}
