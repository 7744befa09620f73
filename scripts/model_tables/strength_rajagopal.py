#!/usr/bin/env python3
"""Set the default model's lower-limb maximum isometric forces to Rajagopal et al. (2016).

Rajagopal A., Dembia C.L., DeMers M.S., Delp D.D., Hicks J.L., Delp S.L. (2016) Full-body
musculoskeletal model for muscle-driven simulation of human gait. IEEE Trans Biomed Eng
63(10):2068-2079. Its forces are F_max = sigma * V / L_opt from MRI muscle volumes V of 24
young healthy adults (Handsfield G.G., Meyer C.H., Hart J.M., Abel M.F., Blemker S.S. (2014)
Relationships of 35 lower limb muscles to height and body mass quantified using MRI
neuroimaging. J Biomech 47(3):631-638), with a specific tension sigma of 60 N/cm^2; the
figures are read from the OpenSim model Models/Rajagopal/Rajagopal2016.osim
(opensim-org/opensim-models), read in place.

gait2392's cadaver-based forces (Delp 1990; Anderson & Pandy 1999) are known to be weak for
young adults. The paths, optimal fibre lengths, tendon slack lengths and pennation angles stay
gait2392's; only max_isometric_force changes, by these rules:

  1. a gait2392 muscle with a Rajagopal2016 counterpart (MATCH below) takes its force;
  2. adductor magnus: gait2392 has three parts, Rajagopal2016 four (Dist, Isch, Mid, Prox);
     the three parts keep gait2392's shares of the muscle's total and are scaled to
     Rajagopal2016's total (the sum of its four parts);
  3. pect, quad_fem, gem and per_tert have no Rajagopal2016 counterpart: gait2392's force is
     kept (listed in KEEP).

The arm already follows MoBL-ARMS 4.1 (Saul et al. 2015) and the lumbar fascicles
Christophy et al. (2012): neither changes. The left side takes the right side's figure
(both models are symmetric).

usage: strength_rajagopal.py GAIT2392.osim RAJAGOPAL2016.osim [data/model/muscles.csv] [--check]
  GAIT2392.osim   Models/Gait2392_Simbody/gait2392_thelen2003muscle.osim (its adductor
                  magnus shares)
  --check   change nothing; exit 1 when the table differs from what the rules give
"""
import csv
import io
import os
import sys
import xml.etree.ElementTree as ET

MATCH = {
    'glut_med1': 'glmed1', 'glut_med2': 'glmed2', 'glut_med3': 'glmed3',
    'glut_min1': 'glmin1', 'glut_min2': 'glmin2', 'glut_min3': 'glmin3',
    'glut_max1': 'glmax1', 'glut_max2': 'glmax2', 'glut_max3': 'glmax3',
    'add_long': 'addlong', 'add_brev': 'addbrev', 'tfl': 'tfl', 'iliacus': 'iliacus',
    'peri': 'piri', 'grac': 'grac', 'sar': 'sart',
    'semimem': 'semimem', 'semiten': 'semiten', 'bifemlh': 'bflh', 'bifemsh': 'bfsh',
    'rect_fem': 'recfem', 'vas_med': 'vasmed', 'vas_int': 'vasint', 'vas_lat': 'vaslat',
    'med_gas': 'gasmed', 'lat_gas': 'gaslat', 'soleus': 'soleus',
    'tib_post': 'tibpost', 'tib_ant': 'tibant', 'per_brev': 'perbrev', 'per_long': 'perlong',
    'flex_dig': 'fdl', 'flex_hal': 'fhl', 'ext_dig': 'edl', 'ext_hal': 'ehl',
}
ADD_MAG_G2392 = ('add_mag1', 'add_mag2', 'add_mag3')
ADD_MAG_RAJ = ('addmagDist', 'addmagIsch', 'addmagMid', 'addmagProx')
KEEP = ('pect', 'quad_fem', 'gem', 'per_tert')
G2392_PREFIX = 'gait2392'
FORCE_NOTE = 'max_isometric_force: Rajagopal et al. 2016 (Handsfield et al. 2014 MRI volumes)'


def right_forces(path):
    """max_isometric_force of every right-side muscle of an OpenSim model, by base name."""
    root = ET.parse(path).getroot()
    forces = {}
    for el in root.iter():
        name = el.get('name')
        f = el.find('max_isometric_force')
        if name and name.endswith('_r') and f is not None:
            forces[name[:-2]] = float(f.text)
    return forces


def fmt(x):
    # shortest form that reads back to the same double
    return repr(float(x)) if float(x) != int(x) else str(int(x))


def original_g2392_source(src):
    """The row's gait2392 source without a previous force note."""
    return src.split('; ' + FORCE_NOTE)[0]


def main():
    args = [a for a in sys.argv[1:] if a != '--check']
    check = '--check' in sys.argv[1:]
    if len(args) < 2:
        sys.exit(__doc__)
    g2392_forces = right_forces(args[0])
    raj = right_forces(args[1])
    table = args[2] if len(args) > 2 else os.path.join(
        os.path.dirname(__file__), '..', '..', 'data', 'model', 'muscles.csv')
    with open(table, newline='') as f:
        rows = list(csv.DictReader(f))
        fields = list(rows[0].keys())
    g2392 = {r['name'][:-2]: r for r in rows if r['side'] == 'r' and r['source'].startswith(G2392_PREFIX)}
    missing = [m for m in MATCH if m not in g2392] + [m for m in MATCH.values() if m not in raj]
    missing += [m for m in ADD_MAG_RAJ if m not in raj]
    if missing:
        sys.exit('missing muscles: %s' % ' '.join(missing))
    g2392_add_mag = {m: g2392_forces[m] for m in ADD_MAG_G2392}
    raj_add_mag = sum(raj[m] for m in ADD_MAG_RAJ)
    new = {}
    for m, r in MATCH.items():
        new[m] = raj[r]
    for m in ADD_MAG_G2392:
        new[m] = g2392_add_mag[m] * raj_add_mag / sum(g2392_add_mag.values())
    unset = sorted(set(g2392) - set(new) - set(KEEP))
    if unset:
        sys.exit('gait2392 muscles without a rule: %s' % ' '.join(unset))
    out = []
    changed = 0
    for r in rows:
        base = r['name'][:-2]
        if r['source'].startswith(G2392_PREFIX) and base in new:
            f = fmt(round(new[base], 6))
            s = original_g2392_source(r['source']) + '; ' + FORCE_NOTE
            if base in ADD_MAG_G2392:
                s += ' (total of addmagDist/Isch/Mid/Prox in gait2392\'s shares)'
            else:
                s += ' (%s)' % MATCH[base]
            if r['max_isometric_force'] != f or r['source'] != s:
                changed += 1
            r = dict(r, max_isometric_force=f, source=s)
        out.append(r)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=fields, lineterminator='\n')
    w.writeheader()
    w.writerows(out)
    if check:
        with open(table, newline='') as f:
            same = f.read() == buf.getvalue()
        print('muscles.csv %s the Rajagopal2016 rules' % ('follows' if same else 'does NOT follow'))
        sys.exit(0 if same else 1)
    with open(table, 'w', newline='') as f:
        f.write(buf.getvalue())
    print('%d rows changed; lower-limb forces from Rajagopal2016 (adductor magnus total %.1f N); kept: %s'
          % (changed, raj_add_mag, ' '.join(KEEP)))


if __name__ == '__main__':
    main()
