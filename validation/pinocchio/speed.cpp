// Pinocchio's per-call time in C++, built against the `pin` wheel's headers and libraries
// (validation/pinocchio/run.sh builds it; speed.py runs it on the states it writes):
//
//     speed_cpp MODEL.xml STATES.bin B K GX GY GZ
//
// MODEL.xml: the MJCF that `musculo export-mjcf` writes, read by pinocchio::mjcf::buildModel.
// STATES.bin: B states of float64, each q, v, a (nv values each, Pinocchio's order).
// G: gravity (Pinocchio's MJCF reader keeps its default −9.81 z, not the file's <option>).
// Two models of the same chain are timed: "mjcf", as the reader builds it (a body's several
// axes become one JointModelComposite), and "unrolled", each composite's axes as separate native
// joints (JointModelRX, ...RevoluteUnaligned, ...PrismaticUnaligned) on massless bodies.
// Each quantity runs one warm-up batch, then K batches of one call per state; a batch gives a
// per-call time (its duration / B). Prints JSON: median, min, max over the batches, in µs.
#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/parsers/mjcf.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

namespace pin = pinocchio;

// Per-call µs of `k` batches of `call(i)` for i < b: {median, min, max}.
template<typename F>
static std::vector<double> time_calls(int b, int k, F call)
{
  for (int i = 0; i < b; ++i)
    call(i);
  std::vector<double> per_call;
  for (int j = 0; j < k; ++j)
  {
    auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < b; ++i)
      call(i);
    std::chrono::duration<double, std::micro> dt = std::chrono::steady_clock::now() - t0;
    per_call.push_back(dt.count() / b);
  }
  std::sort(per_call.begin(), per_call.end());
  return {per_call[per_call.size() / 2], per_call.front(), per_call.back()};
}

static void print_stats(const char * name, const std::vector<double> & s, bool last)
{
  std::printf(
    "  \"%s\": {\"median\": %.6f, \"min\": %.6f, \"max\": %.6f}%s\n", name, s[0], s[1], s[2],
    last ? "" : ",");
}

// The same chain with every composite joint split into its sub-joints, one after the other; the
// body's inertia goes on the last. Configuration and velocity indices stay as they were.
static pin::Model unroll(const pin::Model & model)
{
  pin::Model out;
  out.gravity = model.gravity;
  std::vector<pin::JointIndex> now(model.njoints, 0);
  for (pin::JointIndex i = 1; i < static_cast<pin::JointIndex>(model.njoints); ++i)
  {
    pin::JointIndex parent = now[model.parents[i]];
    pin::SE3 place = model.jointPlacements[i];
    const pin::JointModel::JointModelVariant & j = model.joints[i].toVariant();
    if (const auto * c = boost::get<pin::JointModelComposite>(&j))
    {
      for (size_t k = 0; k < c->joints.size(); ++k)
      {
        const std::string name = model.names[i] + "#" + std::to_string(k);
        parent = out.addJoint(parent, c->joints[k], place * c->jointPlacements[k], name);
        place = pin::SE3::Identity();
      }
    }
    else
      parent = out.addJoint(parent, model.joints[i], place, model.names[i]);
    out.appendBodyToJoint(parent, model.inertias[i], pin::SE3::Identity());
    now[i] = parent;
  }
  return out;
}

// Times the four algorithms on `model` and prints them as the JSON member `label`.
static void time_model(
  const char * label,
  const pin::Model & model,
  const std::vector<Eigen::VectorXd> & q,
  const std::vector<Eigen::VectorXd> & v,
  const std::vector<Eigen::VectorXd> & a,
  int k,
  bool last)
{
  const int b = static_cast<int>(q.size());
  pin::Data data(model);
  const auto m = time_calls(b, k, [&](int i) { pin::crba(model, data, q[i]); });
  const auto nle = time_calls(b, k, [&](int i) { pin::nonLinearEffects(model, data, q[i], v[i]); });
  const auto id = time_calls(b, k, [&](int i) { pin::rnea(model, data, q[i], v[i], a[i]); });
  const auto did =
    time_calls(b, k, [&](int i) { pin::computeRNEADerivatives(model, data, q[i], v[i], a[i]); });
  std::printf(" \"%s\": {\n  \"njoints\": %d,\n", label, static_cast<int>(model.njoints));
  print_stats("crba", m, false);
  print_stats("nonLinearEffects", nle, false);
  print_stats("rnea", id, false);
  print_stats("computeRNEADerivatives", did, true);
  std::printf(" }%s\n", last ? "" : ",");
}

int main(int argc, char ** argv)
{
  if (argc != 8)
  {
    std::fprintf(stderr, "usage: speed_cpp MODEL.xml STATES.bin B K GX GY GZ\n");
    return 2;
  }
  pin::Model model;
  pin::mjcf::buildModel(argv[1], model);
  model.gravity.linear() << std::atof(argv[5]), std::atof(argv[6]), std::atof(argv[7]);
  const int b = std::atoi(argv[3]), k = std::atoi(argv[4]);
  const int nv = model.nv;
  if (model.nq != nv || b <= 0 || k <= 0)
  {
    std::fprintf(stderr, "speed_cpp: nq %d, nv %d, B %d, K %d\n", model.nq, nv, b, k);
    return 1;
  }
  std::vector<double> raw(static_cast<size_t>(b) * 3 * nv);
  std::ifstream in(argv[2], std::ios::binary);
  in.read(reinterpret_cast<char *>(raw.data()), static_cast<std::streamsize>(raw.size() * 8));
  if (!in)
  {
    std::fprintf(stderr, "speed_cpp: %s holds fewer than %d states of 3 x %d\n", argv[2], b, nv);
    return 1;
  }
  std::vector<Eigen::VectorXd> q(b), v(b), a(b);
  for (int i = 0; i < b; ++i)
  {
    const double * row = raw.data() + static_cast<size_t>(i) * 3 * nv;
    q[i] = Eigen::Map<const Eigen::VectorXd>(row, nv);
    v[i] = Eigen::Map<const Eigen::VectorXd>(row + nv, nv);
    a[i] = Eigen::Map<const Eigen::VectorXd>(row + 2 * nv, nv);
  }
  std::printf("{\n \"nv\": %d,\n", nv);
  time_model("mjcf", model, q, v, a, k, false);
  time_model("unrolled", unroll(model), q, v, a, k, true);
  std::printf("}\n");
  return 0;
}
