//! The procedure's figures are stated once, in the code, and the documents say the same: the
//! default square side, the measuring precision the advice assumes, the plausibility bound's
//! tolerances, and the identification's steps.

use odocal::motion::identify::LEVEL_FRACTIONS;
use odocal::session::Settings;
use odocal::session::library::{MEASURED_HEADING_SIGMA_DEG, MEASURED_POSITION_SIGMA_M};
use odocal::session::measure::{
    DIAMETER_RATIO_TOLERANCE, MEASURING_PRECISION_DEG, MEASURING_PRECISION_M, SCALE_TOLERANCE,
    WHEELBASE_TOLERANCE,
};

fn doc(path: &str) -> String {
    let full = format!("{}/{path}", env!("CARGO_MANIFEST_DIR"));
    // Lines are wrapped anywhere: compare with single spaces.
    std::fs::read_to_string(&full)
        .unwrap_or_else(|e| panic!("{full}: {e}"))
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

fn assert_says(text: &str, path: &str, figure: &str) {
    assert!(text.contains(figure), "{path} does not say `{figure}`");
}

fn percent(fraction: f64) -> String {
    format!("{}", (fraction * 100.0).round())
}

#[test]
fn docs_state_the_figures_the_code_holds() {
    let readme = doc("README.md");
    let protocol = doc("docs/protocol.md");
    let operator = doc("docs/operator.md");
    // The default square side.
    let side = Settings::default().square_side_f64();
    assert_says(&readme, "README.md", &format!("default L = {side:.3} m"));
    // The measuring precision the track-size advice is computed for.
    let precision = format!(
        "to about {} mm and {}°",
        MEASURED_POSITION_SIGMA_M * 1e3,
        MEASURED_HEADING_SIGMA_DEG
    );
    assert_says(&readme, "README.md", &precision);
    // The plausibility bound: the tolerances and the measuring allowance.
    let tolerances = format!(
        "diameter ratio `E_d` ±{} %, wheelbase ±{} %, mean diameter ±{} %",
        percent(DIAMETER_RATIO_TOLERANCE),
        percent(WHEELBASE_TOLERANCE),
        percent(SCALE_TOLERANCE)
    );
    assert_says(&protocol, "docs/protocol.md", &tolerances);
    let allowance = format!("{} mm of measuring", (MEASURING_PRECISION_M * 1e3).round());
    assert_says(&protocol, "docs/protocol.md", &allowance);
    assert_says(
        &protocol,
        "docs/protocol.md",
        &format!("plus {}° bounds the heading", MEASURING_PRECISION_DEG),
    );
    let operator_tolerances = format!(
        "±{} % wheel diameter ratio, ±{} % wheelbase, ±{} % mean diameter, plus {} mm and {}°",
        percent(DIAMETER_RATIO_TOLERANCE),
        percent(WHEELBASE_TOLERANCE),
        percent(SCALE_TOLERANCE),
        (MEASURING_PRECISION_M * 1e3).round(),
        MEASURING_PRECISION_DEG
    );
    assert_says(&operator, "docs/operator.md", &operator_tolerances);
    // The identification's steps, as the board's reply states them.
    let steps = LEVEL_FRACTIONS
        .iter()
        .map(|f| percent(*f))
        .collect::<Vec<_>>()
        .join("/");
    assert_says(
        &protocol,
        "docs/protocol.md",
        &format!("steps to {steps} % of max_speed"),
    );
    // The sign hint: a CW square's end is near its start, on either side of it.
    for (path, text) in [("README.md", &readme), ("docs/operator.md", &operator)] {
        assert!(
            !text.contains("square ends near y ≤ 0"),
            "{path} says a CW square ends at y ≤ 0"
        );
    }
}
