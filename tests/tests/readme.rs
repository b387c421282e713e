//! The scenario README shows is one the simulator accepts.

use shoal_scenario::Scenario;

#[test]
fn the_readme_scenario_example_parses() {
    let readme = include_str!("../../README.md");
    // Other sections show TOML too (iceoryx2's configuration).
    let section = readme
        .find("## Scenarios")
        .expect("a Scenarios section in README.md");
    let start = section
        + readme[section..]
            .find("```toml\n")
            .expect("a TOML example in README.md's Scenarios")
        + "```toml\n".len();
    let end = start + readme[start..].find("```").expect("the end of the example");
    let scenario =
        Scenario::from_toml(&readme[start..end], "README.md").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scenario.name, "lab");
    assert_eq!(scenario.formation.neighbours, 4);
    assert_eq!(scenario.arena.surfaces.len(), 1);
}
