"""The images of a block in combination order (Kornus et al. 2006, section 3.3): 0 = the reference (nadir, HRG),
1 = forward (HRS1), 2 = backward (HRS2), as the matching step takes them."""

from ..errors import InputError


def combination_order(rows, text):
    """The block's image rows in combination order: `text` is a comma-separated list of names
    (reference, forward[, backward]); empty or 'all' orders the block's 2 or 3 images itself
    (HRG, HRS1, HRS2 when so named, else block order). InputError for a block of fewer than 2 images,
    whatever `text` names."""
    if len(rows) < 2:
        has = f"one image ({rows[0]['name']})" if rows else "no image"
        raise InputError(
            f"matching needs two or three images of the same ground, and the block has {has}: create a "
            "block with the stereo pair or triplet (pushbroom:createblock with all its images) and match "
            "that"
        )
    by_name = {r["name"]: r for r in rows}
    names = [n.strip() for n in (text or "").split(",") if n.strip()]
    if names and names != ["all"]:
        missing = [n for n in names if n not in by_name]
        if missing:
            raise InputError(f"image(s) {', '.join(missing)} not in the block; it has {', '.join(by_name)}")
        if len(names) not in (2, 3) or len(set(names)) != len(names):
            raise InputError(f"give 2 or 3 different images (reference, forward[, backward]), got {names}")
        return [by_name[n] for n in names]
    if len(rows) not in (2, 3):
        raise InputError(
            f"the block has {len(rows)} images: name the 2 or 3 to match in the Images parameter "
            "(reference, forward[, backward])"
        )
    upper = {r["name"].upper(): r for r in rows}
    if len(rows) == 3 and all(any(k.startswith(p) for k in upper) for p in ("HRG", "HRS1", "HRS2")):
        return [next(r for k, r in upper.items() if k.startswith(p)) for p in ("HRG", "HRS1", "HRS2")]
    return list(rows)
