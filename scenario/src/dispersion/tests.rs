use super::*;

const NOMINAL: &str = r#"
[scenario]
seed = 1
name = "n"
[plant]
mass_kg = 100.0
substeps = 2
mode = "a"
r0_m = [1.0, -2.0, 3.0]
[[agents]]
id = 1
gain = 0.5
"#;

fn nominal() -> toml::Table {
    NOMINAL.parse().unwrap()
}

fn spec(text: &str) -> Result<Dispersions, Vec<Problem>> {
    let t: toml::Table = text.parse().unwrap();
    Dispersions::parse(t[SECTION].clone(), &nominal())
}

fn problems(text: &str) -> String {
    spec(text).unwrap_err().iter().map(|p| format!("{p}\n")).collect()
}

#[test]
fn every_distribution_draws_within_its_support_and_applies() {
    let d = spec(
        r#"
[[dispersions]]
key = "plant.mass_kg"
dist = "truncated-normal"
sigma_rel = 0.1
low = 90.0
high = 105.0
[[dispersions]]
key = "plant.substeps"
dist = "uniform-int"
low = 1
high = 4
[[dispersions]]
key = "plant.mode"
dist = "choice"
values = ["a", "b"]
weights = [1.0, 3.0]
[[dispersions]]
key = "plant.r0_m"
dist = "normal"
sigma = [0.1, 0.2, 0.3]
[[dispersions]]
key = "agents[0].gain"
dist = "log-uniform"
low = 0.1
high = 10.0
"#,
    )
    .unwrap();
    assert_eq!(
        d.columns(),
        [
            "plant.mass_kg",
            "plant.substeps",
            "plant.mode",
            "plant.r0_m[0]",
            "plant.r0_m[1]",
            "plant.r0_m[2]",
            "agents[0].gain"
        ]
    );
    let mut b_count = 0;
    for case in 0..2000 {
        let v = d.draw(7, case);
        let m = v[0].as_float().unwrap();
        assert!((90.0..=105.0).contains(&m), "{m}");
        assert!((1..=4).contains(&v[1].as_integer().unwrap()));
        b_count += usize::from(v[2].as_str() == Some("b"));
        let g = v[6].as_float().unwrap();
        assert!((0.1..=10.0).contains(&g));
        let mut t = nominal();
        d.apply(&mut t, &v);
        assert_eq!(t["plant"]["mass_kg"].as_float(), Some(m));
        assert_eq!(t["plant"]["r0_m"][2], v[5]);
        assert_eq!(t["agents"][0]["gain"].as_float(), Some(g));
    }
    // P(b) = 0.75: 1500 of 2000, binomial σ ≈ 19.
    assert!((1400..1600).contains(&b_count), "{b_count}");
}

#[test]
fn a_case_draws_the_same_whatever_else_is_drawn_and_normals_have_their_moments() {
    let d = spec("[[dispersions]]\nkey = \"plant.mass_kg\"\ndist = \"normal\"\nsigma = 2.0\n").unwrap();
    let bits = |seed, case| d.draw(seed, case)[0].as_float().unwrap().to_bits();
    assert_eq!(bits(3, 17), bits(3, 17));
    assert_ne!(bits(3, 17), bits(3, 18));
    assert_ne!(bits(3, 17), bits(4, 17));
    let xs: Vec<f64> = (0..20_000).map(|c| d.draw(3, c)[0].as_float().unwrap()).collect();
    let mean = xs.iter().sum::<f64>() / xs.len() as f64;
    let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (xs.len() - 1) as f64).sqrt();
    // Standard errors: mean 2/√20000 ≈ 0.014, sd ≈ 0.01.
    assert!((mean - 100.0).abs() < 0.06, "{mean}");
    assert!((sd - 2.0).abs() < 0.05, "{sd}");
}

#[test]
fn a_group_correlates_its_members() {
    let group = |rho: f64| {
        spec(&format!(
            "[[dispersions]]\nkey = \"plant.mass_kg\"\ndist = \"normal\"\nsigma = 1.0\ngroup = \"g\"\ncorrelation = {rho}\n\
             [[dispersions]]\nkey = \"agents[0].gain\"\ndist = \"uniform\"\nlow = 0.0\nhigh = 1.0\ngroup = \"g\"\ncorrelation = {rho}\n"
        ))
        .unwrap()
    };
    let pearson = |d: &Dispersions| {
        let xy: Vec<(f64, f64)> = (0..5000)
            .map(|c| {
                let v = d.draw(1, c);
                (v[0].as_float().unwrap(), law::phi_inv(v[1].as_float().unwrap()))
            })
            .collect();
        let n = xy.len() as f64;
        let (mx, my) = (xy.iter().map(|p| p.0).sum::<f64>() / n, xy.iter().map(|p| p.1).sum::<f64>() / n);
        let cov = xy.iter().map(|(x, y)| (x - mx) * (y - my)).sum::<f64>();
        let (vx, vy) =
            (xy.iter().map(|p| (p.0 - mx).powi(2)).sum::<f64>(), xy.iter().map(|p| (p.1 - my).powi(2)).sum::<f64>());
        cov / (vx * vy).sqrt()
    };
    assert!(pearson(&group(1.0)) > 0.999);
    let r = pearson(&group(0.5));
    // Sampling σ of r near 0.5 with n = 5000 is ≈ 0.011.
    assert!((r - 0.5).abs() < 0.05, "{r}");
    assert!(pearson(&group(0.0)).abs() < 0.05);
}

#[test]
fn bad_specs_are_refused_by_key_path_never_skipped() {
    let e = problems("[[dispersions]]\nkey = \"plant.mas_kg\"\ndist = \"normal\"\nsigma = 1.0\n");
    assert!(
        e.contains("dispersions[0].key = \"plant.mas_kg\": plant has no key \"mas_kg\" (did you mean \"mass_kg\"?)"),
        "{e}"
    );
    let e = problems("[[dispersions]]\nkey = \"agents[3].gain\"\ndist = \"normal\"\nsigma = 1.0\n");
    assert!(e.contains("agents has 1 element(s), no index 3"), "{e}");
    let e = problems("[[dispersions]]\nkey = \"plant.substeps\"\ndist = \"normal\"\nsigma = 1.0\n");
    assert!(e.contains("dispersions[0].dist: the key holds a whole number"), "{e}");
    let e = problems("[[dispersions]]\nkey = \"plant.r0_m\"\ndist = \"normal\"\nsigma = [1.0, 2.0]\n");
    assert!(e.contains("dispersions[0].sigma: 2 values for a key of 3 component(s)"), "{e}");
    let e =
        problems("[[dispersions]]\nkey = \"plant.mass_kg\"\ndist = \"uniform\"\nlow = 2.0\nhigh = 1.0\nsigma = 3.0\n");
    assert!(e.contains("dispersions[0].sigma: not a parameter of uniform"), "{e}");
    let e = problems("[[dispersions]]\nkey = \"plant.mass_kg\"\ndist = \"uniform\"\nlow = 2.0\nhigh = 1.0\n");
    assert!(e.contains("dispersions[0].high: high = 1 must be above low = 2"), "{e}");
    let e = problems("[[dispersions]]\nkey = \"plant.mass_kg\"\ndist = \"gaussian\"\nsigma = 1.0\n");
    assert!(e.contains("dispersions[0].dist = \"gaussian\": must be one of"), "{e}");
    let e = problems("[[dispersions]]\nkey = \"plant.mass_kg\"\ndist = \"normal\"\nsigma = 1.0\nsigmma = 2\n");
    assert!(e.contains("dispersions[0].sigmma: unknown key (did you mean \"sigma\"?)"), "{e}");
    let e = problems("[[dispersions]]\nkey = \"plant.mode\"\ndist = \"choice\"\nvalues = [\"a\", 3]\n");
    assert!(e.contains("dispersions[0].values[1] = 3: the key holds a string"), "{e}");
    let e = problems("[[dispersions]]\nkey = \"scenario.seed\"\ndist = \"uniform-int\"\nlow = 1\nhigh = 3\n");
    assert!(e.contains("the campaign sets each case's seed"), "{e}");
    let e = problems(
        "[[dispersions]]\nkey = \"plant.r0_m\"\ndist = \"normal\"\nsigma = 1.0\n\
         [[dispersions]]\nkey = \"plant.r0_m[1]\"\ndist = \"normal\"\nsigma = 1.0\n",
    );
    assert!(e.contains("dispersions[1].key = \"plant.r0_m[1]\": overlaps dispersions[0]"), "{e}");
    let e = problems("[[dispersions]]\nkey = \"plant.mass_kg\"\ndist = \"log-uniform\"\nlow = 0.0\nhigh = 1.0\n");
    assert!(e.contains("a log-uniform needs low > 0"), "{e}");
    let e = problems("[[dispersions]]\nkey = \"plant.mass_kg\"\ndist = \"normal\"\nsigma = 1.0\ncorrelation = 0.5\n");
    assert!(e.contains("dispersions[0].correlation = 0.5: a correlation needs a group"), "{e}");
    // The entries are named by their place in the file, also past a refused one.
    let e = problems(
        "[[dispersions]]\nkey = \"plant.x\"\ndist = \"normal\"\nsigma = 1.0\n\
         [[dispersions]]\nkey = \"plant.mass_kg\"\ndist = \"normal\"\nsigma = 1.0\n\
         [[dispersions]]\nkey = \"plant.mass_kg\"\ndist = \"normal\"\nsigma = 2.0\n",
    );
    assert!(e.contains("dispersions[2].key = \"plant.mass_kg\": overlaps dispersions[1]"), "{e}");
    // A σ from sigma_rel is blamed on sigma_rel.
    let e = problems("[[dispersions]]\nkey = \"plant.mass_kg\"\ndist = \"normal\"\nsigma_rel = -0.1\n");
    assert!(e.contains("dispersions[0].sigma_rel: σ = -10"), "{e}");
    let e = problems("dispersions = []\n");
    assert!(e.contains("dispersions: empty"), "{e}");
    // Every entry's problems at once.
    let e = spec(
        "[[dispersions]]\nkey = \"plant.x\"\ndist = \"normal\"\nsigma = 1.0\n\
         [[dispersions]]\nkey = \"plant.mass_kg\"\ndist = \"normal\"\n",
    )
    .unwrap_err();
    assert_eq!(e.len(), 2, "{e:?}");
    assert!(e[1].to_string().contains("dispersions[1].sigma: required for normal: sigma or sigma_rel"), "{e:?}");
}

#[test]
fn a_problem_is_blamed_on_the_dispersion_of_its_key() {
    let d = spec(
        "[[dispersions]]\nkey = \"plant.r0_m\"\ndist = \"normal\"\nsigma = 1.0\n\
         [[dispersions]]\nkey = \"agents[0].gain\"\ndist = \"normal\"\nsigma = 1.0\n",
    )
    .unwrap();
    assert_eq!(d.blame("plant.r0_m[2]"), Some(0));
    assert_eq!(d.blame("agents[0].gain"), Some(1));
    assert_eq!(d.blame("agents[0].gains"), None);
    assert_eq!(d.blame("plant.mass_kg"), None);
}

#[test]
fn a_launch_ignores_the_dispersions() {
    let ring =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../topologies/consensus-ring.toml")).unwrap();
    let with =
        format!("{ring}\n[[dispersions]]\nkey = \"scenario.dt_s\"\ndist = \"uniform\"\nlow = 0.01\nhigh = 0.02\n");
    let o = crate::Overrides::default();
    let p = |t: &str| crate::parse(t, std::path::Path::new("x.toml"), &o).unwrap();
    assert_eq!(p(&with).scenario.dt_s, p(&ring).scenario.dt_s);
}
