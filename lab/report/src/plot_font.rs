//! The one font every plot draws with: DejaVu Sans (compiled in), registered with plotters
//! as `sans-serif` once per process.

/// Register DejaVu Sans as plotters' `sans-serif` (idempotent; every plot calls it first).
pub fn register() {
    use std::sync::Once;
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ =
            plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, dejavu::sans::regular());
    });
}
