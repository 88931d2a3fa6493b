//! `--holdout` values, from the user's side: what parses, and what a bad one says in each
//! spelling (the CLI's and Python's).

use qfa_calibrate::static_cal::Holdout;
use qfa_log::spelling::Spelling;

#[test]
fn holdout_values_parse_and_bad_ones_say_what_is_allowed() {
    assert_eq!("auto".parse::<Holdout>().unwrap(), Holdout::Auto);
    assert_eq!("after-max".parse::<Holdout>().unwrap(), Holdout::AfterMax);
    assert_eq!("blocks:7".parse::<Holdout>().unwrap(), Holdout::Blocks(7));
    assert_eq!("none".parse::<Holdout>().unwrap(), Holdout::None);
    for bad in ["blocks:1", "blocks:x", "ramps", ""] {
        let e = bad.parse::<Holdout>().unwrap_err().to_string();
        assert_eq!(e, format!("--holdout `{bad}`: expected auto, after-max, blocks:K (K ≥ 2) or none"));
    }
    let e = "ramps".parse::<Holdout>().unwrap_err();
    assert_eq!(e.message(Spelling::Python), "holdout=\"ramps\": expected auto, after-max, blocks:K (K ≥ 2) or none");
}
