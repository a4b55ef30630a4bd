#include "app/ingest.hpp"

#include "tracker.hpp"

namespace cutload::app {

motion_io::IngestReport inspect_log(const std::string& path, const motion_io::ReadOptions& options) {
    return motion_io::inspect(path, options);
}

IngestedLog ingest_log(const std::string& path, const motion_io::ReadOptions& options, const Control& control) {
    return cancellable(control, [&] {
        Tracker track(control);
        track.begin(Phase::Ingest, 0, 1);
        IngestedLog log;
        log.motion = motion_io::ingest(path, options, &log.report);
        track.done();
        return log;
    });
}

Resampled resample_log(const std::string& path, const motion_io::ReadOptions& options, const std::string& out_csv) {
    Resampled r;
    r.rows = motion_io::resample_to_csv(path, options, out_csv, &r.report);
    return r;
}

}  // namespace cutload::app
