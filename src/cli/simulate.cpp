// `simulate`: runs a saved model on a record's displacement and writes the simulated force.
#include <iostream>
#include <sstream>

#include "commands.hpp"

namespace friction::cli {

namespace {

struct SimulateOptions {
  std::string model_file;
  std::string data;
  InputOptions input;
  OutputOptions output;
};

int run_simulate(const SimulateOptions& o) {
  AnyModel model = load_model(o.model_file);
  const Record record = load_record(o.data, o.input, /*require_force=*/false);
  for (const auto& w : record.conditioning.warnings) std::cerr << "warning: " << w << "\n";
  const std::vector<double> simulated = model.simulate(record);

  std::vector<CsvColumn> columns{{"time", record.time}, {"displacement", record.measured()}};
  std::vector<double> residual;
  if (record.has_force()) {
    residual.resize(record.size());
    for (std::size_t k = 0; k < record.size(); ++k) residual[k] = record.force[k] - simulated[k];
    columns.push_back({"force", record.force});
  }
  columns.push_back({"simulated", simulated});
  if (record.has_force()) columns.push_back({"residual", residual});
  emit_stream(o.output, [&](std::ostream& s) { write_csv(s, columns); });
  return kExitOk;
}

}  // namespace

Action register_simulate(CLI::App& root) {
  auto o = std::make_shared<SimulateOptions>();
  CLI::App* c = root.add_subcommand("simulate",
                                    "Run a saved model on the displacement of a record; write "
                                    "time,displacement,force,simulated,residual as CSV");
  c->add_option("--model-file", o->model_file, "Saved model (JSON), or a document containing one")
      ->required();
  c->add_option("--data", o->data, "Record (CSV) whose displacement drives the model")->required();
  add_input_options(*c, o->input);
  c->add_option("--out", o->output.out, "Write the CSV to FILE (atomically) instead of stdout");
  return [o] { return run_simulate(*o); };
}

}  // namespace friction::cli
