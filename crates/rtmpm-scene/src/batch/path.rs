//! Field paths of a scene (`material[0].yield_stress`, `gravity[1]`, `time.damping`): parsed,
//! read from and written into the scene's TOML table.

use toml::{Table, Value};

/// One step of a path: a table's key or an array's index.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Seg {
    Key(String),
    Index(usize),
}

/// Split `material[1].poisson_ratio` into `material`, `1`, `poisson_ratio`; `Err` names what is
/// wrong with the path's spelling.
pub fn parse(path: &str) -> Result<Vec<Seg>, String> {
    let mut segs = Vec::new();
    if path.is_empty() {
        return Err("the path is empty".into());
    }
    for part in path.split('.') {
        let (key, mut rest) = match part.find('[') {
            Some(i) => (&part[..i], &part[i..]),
            None => (part, ""),
        };
        if key.is_empty() && segs.is_empty() {
            return Err(format!("`{path}` does not start with a field name"));
        }
        if key.is_empty() && rest.is_empty() {
            return Err(format!("`{path}` has an empty part between two dots"));
        }
        if !key.is_empty() {
            if !key
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
            {
                return Err(format!("`{key}` in `{path}` is not a field name"));
            }
            segs.push(Seg::Key(key.to_string()));
        }
        while !rest.is_empty() {
            let Some(inner) = rest.strip_prefix('[') else {
                return Err(format!("`{part}` in `{path}`: text after `]`"));
            };
            let Some(end) = inner.find(']') else {
                return Err(format!("`{part}` in `{path}`: `[` without `]`"));
            };
            let i = inner[..end].parse::<usize>().map_err(|_| {
                format!(
                    "`[{}]` in `{path}` is not an index (a whole number from 0)",
                    &inner[..end]
                )
            })?;
            segs.push(Seg::Index(i));
            rest = &inner[end + 1..];
        }
    }
    Ok(segs)
}

/// What a path points at in a scene's table.
#[derive(Debug, PartialEq)]
pub enum Target<'a> {
    /// A value the file gives.
    Found(&'a Value),
    /// A key the file leaves out, inside a table it has (an optional field, or a misspelt one:
    /// the validation of the scene tells).
    Absent,
    /// The path leaves the file: the part that does not exist and why.
    Missing(String),
}

/// Look `segs` up in `root`.
pub fn lookup<'a>(root: &'a Table, segs: &[Seg]) -> Target<'a> {
    let mut table = Some(root);
    let mut value: Option<&Value> = None;
    let mut walked = String::new();
    for (n, seg) in segs.iter().enumerate() {
        let last = n + 1 == segs.len();
        let next = match (seg, table, value) {
            (Seg::Key(k), Some(t), _) => match t.get(k) {
                Some(v) => v,
                None if last => return Target::Absent,
                None => {
                    return Target::Missing(format!(
                        "{} has no `{k}`",
                        where_(&walked, "the scene")
                    ));
                }
            },
            (Seg::Index(i), None, Some(Value::Array(a))) => match a.get(*i) {
                Some(v) => v,
                None => {
                    return Target::Missing(format!(
                        "`{walked}` has {} entries, so no [{i}] (indices start at 0)",
                        a.len()
                    ));
                }
            },
            (Seg::Key(k), None, Some(_)) => {
                return Target::Missing(format!("`{walked}` is not a table, so has no `{k}`"));
            }
            (Seg::Index(i), _, _) => {
                return Target::Missing(format!(
                    "{} is not a list, so has no [{i}]",
                    where_(&walked, "the scene")
                ));
            }
            (Seg::Key(_), None, None) => return Target::Missing(String::new()),
        };
        push_seg(&mut walked, seg);
        table = next.as_table();
        value = Some(next);
    }
    match value {
        Some(v) => Target::Found(v),
        None => Target::Missing("the path is empty".into()),
    }
}

fn where_(walked: &str, root: &str) -> String {
    if walked.is_empty() {
        root.to_string()
    } else {
        format!("`{walked}`")
    }
}

fn push_seg(walked: &mut String, seg: &Seg) {
    match seg {
        Seg::Key(k) if walked.is_empty() => walked.push_str(k),
        Seg::Key(k) => {
            walked.push('.');
            walked.push_str(k);
        }
        Seg::Index(i) => walked.push_str(&format!("[{i}]")),
    }
}

/// Write `v` at `segs` in `root`, which [`lookup`] found (or found [`Target::Absent`]).
pub fn set(root: &mut Table, segs: &[Seg], v: Value) -> Result<(), String> {
    let Some((last, parents)) = segs.split_last() else {
        return Err("the path is empty".into());
    };
    let Some(Seg::Key(first)) = parents.first().or(Some(last)) else {
        return Err("a path starts with a field name".into());
    };
    if parents.is_empty() {
        root.insert(first.clone(), v);
        return Ok(());
    }
    let mut cur = root.get_mut(first).ok_or_else(|| format!("no `{first}`"))?;
    for seg in &parents[1..] {
        cur = step_mut(cur, seg)?;
    }
    match (last, cur) {
        (Seg::Key(k), Value::Table(t)) => {
            t.insert(k.clone(), v);
            Ok(())
        }
        (Seg::Index(i), Value::Array(a)) if *i < a.len() => {
            a[*i] = v;
            Ok(())
        }
        _ => Err("the path does not lead to a value".into()),
    }
}

fn step_mut<'a>(cur: &'a mut Value, seg: &Seg) -> Result<&'a mut Value, String> {
    match (seg, cur) {
        (Seg::Key(k), Value::Table(t)) => t.get_mut(k).ok_or_else(|| format!("no `{k}`")),
        (Seg::Index(i), Value::Array(a)) => a.get_mut(*i).ok_or_else(|| format!("no [{i}]")),
        _ => Err("the path does not lead to a value".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str) -> Table {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn paths_parse_into_keys_and_indices() {
        assert_eq!(
            parse("material[1].yield_stress").unwrap(),
            vec![
                Seg::Key("material".into()),
                Seg::Index(1),
                Seg::Key("yield_stress".into())
            ]
        );
        assert_eq!(
            parse("gravity[1]").unwrap(),
            vec![Seg::Key("gravity".into()), Seg::Index(1)]
        );
        for bad in ["", "[0]", "a..b", "a[x]", "a[-1]", "a[1", "a[1]b", "a b"] {
            assert!(parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn lookup_finds_values_absent_keys_and_missing_parts() {
        let t = table(
            "gravity = [0, -9.8, 0]\n[time]\nduration = 1.0\n[[material]]\nname = \"a\"\nyield_stress = 5\n",
        );
        let at = |p: &str| lookup(&t, &parse(p).unwrap());
        assert_eq!(at("gravity[1]"), Target::Found(&Value::Float(-9.8)));
        assert_eq!(
            at("material[0].yield_stress"),
            Target::Found(&Value::Integer(5))
        );
        assert_eq!(at("time.damping"), Target::Absent);
        assert!(
            matches!(at("material[1].yield_stress"), Target::Missing(m) if m.contains("1 entries"))
        );
        assert!(matches!(at("solver.flip"), Target::Missing(m) if m.contains("no `solver`")));
        assert!(matches!(at("gravity[3]"), Target::Missing(_)));
        assert!(matches!(at("time[0]"), Target::Missing(m) if m.contains("not a list")));
        assert!(matches!(at("gravity.x"), Target::Missing(m) if m.contains("not a table")));
    }

    #[test]
    fn set_writes_where_lookup_points() {
        let mut t =
            table("gravity = [0, -9.8, 0]\n[time]\nduration = 1.0\n[[material]]\nname = \"a\"\n");
        set(&mut t, &parse("gravity[1]").unwrap(), Value::Float(-1.5)).unwrap();
        set(&mut t, &parse("time.damping").unwrap(), Value::Float(0.5)).unwrap();
        set(
            &mut t,
            &parse("material[0].yield_stress").unwrap(),
            Value::Integer(7),
        )
        .unwrap();
        set(&mut t, &parse("seed").unwrap(), Value::Integer(3)).unwrap();
        let at = |p: &str| match lookup(&t, &parse(p).unwrap()) {
            Target::Found(v) => v.clone(),
            other => panic!("{p}: {other:?}"),
        };
        assert_eq!(at("gravity[1]"), Value::Float(-1.5));
        assert_eq!(at("time.damping"), Value::Float(0.5));
        assert_eq!(at("material[0].yield_stress"), Value::Integer(7));
        assert_eq!(at("seed"), Value::Integer(3));
    }
}
