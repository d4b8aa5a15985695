//! The parameter table (`scene::params`) is the one declaration: the README's key table and
//! docs/PARAMETERS.md say what it says, and a scene file's range check is the table's.

use termtrace::scene::Scene;
use termtrace::scene::params::{Param, reference_table};
use termtrace::ui::keys::help_lines;

fn readme() -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap()
}

/// The rows of the README's key table: `| keys | what they do |`.
fn readme_key_rows() -> Vec<(String, String)> {
    let text = readme();
    let start = text
        .find("| keys | what they do |")
        .expect("README has a key table");
    text[start..]
        .lines()
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .map(|l| {
            let cells: Vec<&str> = l.trim_matches('|').split(" | ").collect();
            (cells[0].trim().to_string(), cells[1].trim().to_string())
        })
        .collect()
}

#[test]
fn the_readme_key_table_is_the_help() {
    let rows = readme_key_rows();
    let help = help_lines();
    assert_eq!(
        rows.iter().map(|r| &r.0).collect::<Vec<_>>(),
        help.iter().map(|h| &h.0).collect::<Vec<_>>(),
        "the README's keys, in order, are the help's"
    );
    // The parameters' lines are generated from the table and must read the same.
    for (keys, what) in termtrace::scene::params::help_lines() {
        assert!(
            rows.contains(&(keys.clone(), what.clone())),
            "README lacks the row `| {keys} | {what} |`"
        );
    }
}

#[test]
fn docs_parameters_holds_the_table() {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/PARAMETERS.md"))
        .unwrap();
    let table = reference_table();
    assert!(
        doc.contains(&table),
        "docs/PARAMETERS.md differs from the table; it should contain:\n{table}"
    );
}

#[test]
fn every_key_reaches_its_parameter() {
    use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyModifiers};
    use termtrace::ui::keys::{Action, action};
    for p in Param::all() {
        let key = KeyEvent::new(KeyCode::Char(p.spec().key), KeyModifiers::NONE);
        // A key may serve one parameter of each material model: the selected material's
        // model picks (`App::active_param`).
        let Some(Action::Choose(chosen)) = action(key) else {
            panic!("{}: its key chooses nothing", p.name());
        };
        assert_eq!(chosen.for_model(p.spec().model), p, "{}", p.name());
    }
}

#[test]
fn a_number_of_another_model_is_refused_by_name() {
    let text = "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmetallic = 1\n";
    let err = Scene::from_toml(text, "t.toml").unwrap_err().to_string();
    assert!(
        err.contains("t.toml:4:")
            && err.contains("`metallic` belongs to another material model than `lecture`"),
        "{err}"
    );
    let text = "[materials.gold]\nmodel = \"pbr\"\nsmoothness = 1\n";
    let err = Scene::from_toml(text, "t.toml").unwrap_err().to_string();
    assert!(
        err.contains("`smoothness` belongs to another material model than `pbr`"),
        "{err}"
    );
    let text = "[materials.gold]\nmodel = \"pbs\"\n";
    let err = Scene::from_toml(text, "t.toml").unwrap_err().to_string();
    assert!(err.contains("unknown material model `pbs`"), "{err}");
}

#[test]
fn a_scene_file_is_checked_against_the_declared_range() {
    for p in Param::all() {
        let s = p.spec();
        let Some((table, key)) = s.toml else { continue };
        let outside = if s.range.hi < f64::MAX {
            s.range.hi + 1.0
        } else {
            s.range.lo - 1.0
        };
        // A pbr material's number is a key of a `model = "pbr"` material.
        let model = match s.model {
            Some(m) => format!("model = {:?}\n", m.name()),
            None => String::new(),
        };
        let body = format!("{model}{key} = {outside}");
        let text = match table {
            "material" => format!("[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n{body}\n"),
            _ => format!("[{table}]\n{body}\n"),
        };
        let err = Scene::from_toml(&text, "t.toml")
            .expect_err(&format!("{key} = {outside} is outside {:?}", s.range))
            .to_string();
        assert!(
            err.contains(&s.range.describe()) || err.contains("integer from"),
            "{key}: {err}"
        );
        // Its default is accepted.
        if let Some(d) = s.default {
            let body = if s.step == termtrace::scene::params::Step::Count {
                format!("{model}{key} = {}", d as u32)
            } else {
                format!("{model}{key} = {d:?}")
            };
            let text = match table {
                "material" => format!("[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n{body}\n"),
                _ => format!("[{table}]\n{body}\n"),
            };
            Scene::from_toml(&text, "t.toml").unwrap_or_else(|e| panic!("{key}: {e}"));
        }
    }
}
