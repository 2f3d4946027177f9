// `generate`: a synthetic record from a model, an excitation, extension effects, noise and a seed.
//
// The system is driven by the true displacement; the record then stores what instruments would
// give: the force with white Gaussian noise, the displacement rounded to the encoder resolution.
#include <cmath>
#include <iostream>
#include <numbers>
#include <sstream>

#include "commands.hpp"
#include "friction/excitation.hpp"

namespace friction::cli {

namespace {

struct GenerateOptions {
  std::string model = "maxwell-slip";
  std::string model_file;
  std::string excitation = "combined";
  double rate = 1000.0;
  double presliding_amplitude = 0;  // 0: the excitation's default
  double stroke = 0;
  std::vector<double> speeds;
  int cycles = 0;
  double duration = 0;
  double noise = 0;
  double resolution = 0;
  std::uint64_t seed = 1;
  std::vector<std::string> effects;
  double normal_force = 0;
  std::string truth;
  OutputOptions output;
};

double reference_force(const AnyModel& model) {
  return std::visit([](const auto& m) { return m.reference_force(); }, model.variant());
}

int run_generate(const GenerateOptions& o) {
  // The system: a saved model or the reference system of the type, plus the effects asked for.
  AnyModel model = o.model_file.empty() ? reference_model(check_model_type(o.model), o.rate)
                                        : load_model(o.model_file);
  ExtensionParameters<double> ext = model.extensions();
  for (const auto& spec : o.effects) parse_effect(spec, ext);
  model = model.with_extensions(ext);

  ExcitationOptions e;
  e.kind = parse_excitation_kind(o.excitation);
  e.rate = o.rate;
  e.seed = o.seed;
  if (o.presliding_amplitude > 0) e.presliding_amplitude = o.presliding_amplitude;
  if (o.stroke > 0) e.stroke = o.stroke;
  if (!o.speeds.empty()) e.speeds = o.speeds;
  if (o.cycles > 0) e.presliding_cycles = o.cycles;
  if (o.duration > 0) e.multisine_duration = o.duration;
  const Signal signal = make_excitation(e);

  Record record;
  record.time = signal.time;
  record.displacement = signal.displacement;
  // A normal force varying slowly and independently of the motion (two cycles over the record,
  // +-30 %), about the level at which the model's sliding force is friction_coefficient * N.
  double normal_mean = o.normal_force;
  if (ext.normal_load && normal_mean <= 0)
    normal_mean = reference_force(model) / ext.normal_load->friction_coefficient;
  if (normal_mean > 0) {
    const double duration = record.time.back();
    for (double t : record.time)
      record.normal.push_back(normal_mean *
                              (1 + 0.3 * std::sin(2 * std::numbers::pi * 2 * t / duration)));
  }
  record.force = model.simulate(record);

  NormalSource noise(o.seed ^ 0x9E3779B97F4A7C15ULL);
  add_white_noise(record.force, o.noise, noise);
  quantise(record.displacement, o.resolution);

  if (o.output.out.empty()) {
    std::ostringstream csv;
    write_record_csv(csv, record);
    emit(o.output, csv.str());
  } else {
    write_record_csv(o.output.out, record);
  }
  if (!o.truth.empty()) {
    OutputOptions truth{"json", o.truth};
    Json doc = new_document("generate");
    doc["model"] = model.to_json();
    emit(truth, doc.dump(2) + "\n");
  }
  if (!o.output.out.empty()) {
    // With the record in a file, stdout tells what was generated.
    Json doc = new_document("generate");
    doc["model"] = model.to_json();
    doc["record"] = {{"file", o.output.out},           {"samples", record.size()},
                     {"duration", record.time.back()}, {"rate", o.rate},
                     {"excitation", o.excitation},     {"noise", o.noise},
                     {"resolution", o.resolution},     {"seed", o.seed},
                     {"normal", record.has_normal()}};
    if (o.output.format == "json") {
      std::cout << doc.dump(2) << "\n";
    } else {
      std::cout << "generated " << record.size() << " samples (" << record.time.back() << " s at "
                << o.rate << " Hz, " << o.excitation << ") from a " << model.type()
                << " model into " << o.output.out << "\n"
                << "noise " << o.noise << " N, encoder resolution " << o.resolution << " m, seed "
                << o.seed << "\n";
      if (!ext.empty()) std::cout << "effects: " << extensions_to_json(ext).dump() << "\n";
    }
  }
  return kExitOk;
}

}  // namespace

Action register_generate(CLI::App& root) {
  auto o = std::make_shared<GenerateOptions>();
  CLI::App* c = root.add_subcommand("generate",
                                    "Write a synthetic record from a model, an "
                                    "excitation, effects, noise and a seed");
  c->add_option("--model", o->model,
                "Model type: maxwell-slip, dnlrx, lugre, gms, static "
                "(its reference system)")
      ->capture_default_str();
  c->add_option("--model-file", o->model_file, "Use this saved model instead (JSON)");
  c->add_option("--excitation", o->excitation, "presliding, strokes, multisine or combined")
      ->check(CLI::IsMember({"presliding", "strokes", "multisine", "combined"}))
      ->capture_default_str();
  c->add_option("--rate", o->rate, "Sampling rate [Hz]")->capture_default_str();
  c->add_option("--presliding-amplitude", o->presliding_amplitude,
                "Largest presliding amplitude [m] (default 20e-6)");
  c->add_option("--stroke", o->stroke, "Stroke length, end to end [m] (default 1e-3)");
  c->add_option("--speeds", o->speeds, "Stroke speeds [m/s] (default 2e-4,5e-4,1e-3,2e-3,5e-3)")
      ->delimiter(',');
  c->add_option("--cycles", o->cycles, "Presliding cycles of decreasing amplitude (default 8)");
  c->add_option("--duration", o->duration, "Multisine duration [s] (default 10)");
  c->add_option("--noise", o->noise, "Standard deviation of white Gaussian force noise [N]")
      ->capture_default_str();
  c->add_option("--resolution", o->resolution, "Encoder resolution: displacement quantum [m]")
      ->capture_default_str();
  c->add_option("--seed", o->seed, "Seed of the noise and the multisine phases")
      ->capture_default_str();
  c->add_option("--effect", o->effects,
                "Add an effect of methods.md 7: NAME=VALUE[,param=value...], e.g. viscous=40, "
                "stribeck=2.2,stribeck_velocity=1e-3, inertia=0.5; repeatable");
  c->add_option("--normal-force", o->normal_force,
                "Mean of a recorded normal force [N] (default: only with normal-load)");
  c->add_option("--truth", o->truth, "Also write the generating model (JSON) to this file");
  add_output_options(*c, o->output);
  return [o] { return run_generate(*o); };
}

}  // namespace friction::cli
