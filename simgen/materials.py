"""The scene's materials as a 905 nm LiDAR sees them: one table, with where each value comes from.

`Material.reflectivity` is the reading of a surface at normal incidence on the scale of a
diffuse (Lambertian) reflectivity: what a calibrated sensor reports for it (KITTI's HDL-64E:
a pedestrian, clothes and skin of about 0.5 seen over a cylinder, mean cos pi/4, reads a median
0.36, see `benchmarks/lidar_reflectance_stats.py` and the class breakdown in `results/lidar.md`;
the scale is about 1). The sensor side (per-laser gain, scatter, floor, quantisation) is
`simgen.lidar`.

How a reading falls with the angle of incidence (`incidence_exponent`, reading ~ cos ** k):
- 1, Lambert: smooth or painted surfaces (car paint, walls, poles, bark).
- 0, no fall-off: dark rough particulate ground (asphalt, paving, soil, sand). Single scattering
  from a dark porous surface follows the Lommel-Seeliger law, whose backscatter does not depend
  on the incidence (the full Moon shows no limb darkening). KITTI's road agrees: its median
  reading is 0.22-0.27 from cos 0.4 down to cos 0.05 (benchmarks/lidar_reflectance_stats.py,
  section 2), where a Lambertian road would fall eightfold.
- 0 for leaf volumes too (crowns, hedges, grass): the beam meets leaves of every orientation
  inside the crown whatever the orientation of the crown's outer mesh. For a spherical leaf-angle
  distribution the leaves a beam hits face it at mean cos E[cos^2]/E[cos] = 2/3, so a leaf layer
  reads 2/3 of the leaf reflectance.
- > 1 for retro-reflectors, whose return falls faster than Lambert's with the entrance angle.

Retro-reflectors are given as pi x their coefficient of retroreflection R_A (cd lx^-1 m^-2):
a Lambertian surface of reflectivity rho has R_A = rho / pi (in the sensor's backscatter
geometry), so pi x R_A is the equivalent reflectivity; every retro-reflector here is far above
1, i.e. saturated, as KITTI's 0.99 readings on plates and lamps are. Road markings are given as
pi x their coefficient of retroreflected luminance R_L (EN 1436), the same equivalence at the
grazing angles the sensor sees them at.

Colours to 905 nm. What darkens a paint, a dye or a plastic across the whole spectrum is carbon
black, which absorbs the near infrared as well; the chromatic pigments and dyes (iron-oxide and
organic reds, phthalocyanine blues and greens, most textile dyes) are largely transparent there,
so the layer under them, or the binder's scattering, sets the NIR reflectance (Levinson, Berdahl
& Akbari 2005, "Solar spectral optical properties of pigments", Solar Energy Mat. & Solar Cells
89; PPG's and BASF's work on LiDAR-reflective dark car paints starts from carbon black
absorbing "nearly all" of a 905 nm pulse). So the 905 nm reflectance follows the colour's
brightest channel, from about 0.05 for carbon black to about 0.85 for a TiO2 white
(`nir_reflectivity`).
"""

from __future__ import annotations

from dataclasses import replace

from .world import Material

NIR_BLACK = 0.05  # carbon-black paint or dye at 905 nm (Levinson et al. 2005: < 0.1 across the NIR)
NIR_WHITE = 0.85  # TiO2 (rutile) white paint at 905 nm (Levinson et al. 2005: about 0.8-0.9)


def nir_reflectivity(color) -> float:
    """905 nm reflectance of a paint or dye of this linear-RGB colour: linear in its brightest
    channel, from NIR_BLACK (no colour left: carbon black) to NIR_WHITE (white)."""
    v = max(float(c) for c in color)
    return round(NIR_BLACK + (NIR_WHITE - NIR_BLACK) * min(max(v, 0.0), 1.0), 4)


def paint_material(name: str, color) -> Material:
    """A painted, dyed or coloured surface: Lambertian, reflectance from its colour."""
    c = tuple(float(v) for v in color)
    return Material(name, c, nir_reflectivity(c))


# --- Ground. -------------------------------------------------------------------------------
# Aged asphalt: the binder wears off the aggregate and NIR reflectance rises from about 0.05
# (new) to about 0.2 (Herold & Roberts 2004, Santa Barbara asphalt road spectral library);
# KITTI's roads read a median 0.24 at 4-20 m. Lommel-Seeliger (see above). To the camera: solar
# reflectance about 0.05 new, 0.10-0.18 aged, with the aggregate (pavement albedo surveys, e.g.
# Pomerantz et al., LBNL); city streets are mostly aged, and the visible lies a little below the
# solar figure, which the near infrared raises: 0.12.
ASPHALT = Material("asphalt", (0.12, 0.12, 0.13), 0.20, incidence_exponent=0.0)
# White line paint with glass beads, dry, in service: R_L >= 100 mcd m^-2 lx^-1 (EN 1436 class R2,
# the common minimum for white markings); pi x 0.100 = 0.31, flat over the grazing angles.
MARKING = Material("marking", (0.85, 0.85, 0.82), 0.31, incidence_exponent=0.0)
# Concrete, 905 nm: about 0.35 (ECOSTRESS/ASTER spectral library, construction concrete 0.3-0.4).
# A curb's formed face is smooth (Lambert); paving is rough ground (no fall-off).
CONCRETE = Material("curb", (0.45, 0.45, 0.43), 0.35)
SIDEWALK = Material("sidewalk", (0.32, 0.31, 0.30), 0.30, incidence_exponent=0.0)
# Grass: a leaf volume (green leaves 0.50 at 905 nm, see FOLIAGE) x 2/3.
VERGE = Material("verge", (0.14, 0.20, 0.08), 0.33, incidence_exponent=0.0)
# Leaf litter and soil: dry litter about 0.3, moist soil about 0.2 at 905 nm (ECOSTRESS library).
FOREST_FLOOR = Material("forest_floor", (0.09, 0.07, 0.04), 0.25, incidence_exponent=0.0)
# Dry quartz sand: about 0.5 at 905 nm (USGS spectral library).
SAND = Material("sand", (0.62, 0.52, 0.36), 0.50, incidence_exponent=0.0)

# --- Vegetation and street furniture. ------------------------------------------------------
# Bark: 0.25-0.35 at 905 nm (ECOSTRESS library, tree bark); 0.30.
BARK = Material("bark", (0.12, 0.08, 0.05), 0.30)
# A green leaf in the camera's channels (R, G, B): its reflectance; it passes about half as much
# as it reflects (broadleaf trees' leaves in the Community Land Model: visible reflectance 0.10 and
# transmittance 0.05, near infrared 0.45 and 0.25; Oleson et al. 2013, CLM 4.5 technical note,
# table 3.1).
LEAF = (0.08, 0.20, 0.06)
LEAF_TRANSMITTANCE_RATIO = 0.5


def canopy_reflectance(leaf, transmittance_ratio: float = LEAF_TRANSMITTANCE_RATIO) -> tuple[float, ...]:
    """What the camera sees of a closed crown, hedge or shrub mass of leaves of reflectance `leaf`
    (per channel): the reflectance of a deep layer of leaves that each scatter w = rho (1 + tau /
    rho) of the light they meet, (1 - sqrt(1 - w)) / (1 + sqrt(1 - w)) (the two-stream albedo of a
    semi-infinite layer of isotropic scatterers; Sellers 1985, Int. J. Remote Sensing 6). Light
    that enters a crown meets leaf after leaf, and in the visible each keeps little of it: CLM's
    leaves give 0.04 in the visible and 0.29 in the near infrared, the few per cent and about 0.3
    measured above broadleaf forests in summer. A leaf seen alone would be two to three times
    brighter. (The LiDAR reads the first leaf its own beam lights, with no shade between: `FOLIAGE`'s
    reflectivity stays the leaf's.)"""
    out = []
    for rho in leaf:
        k = (1.0 - rho * (1.0 + transmittance_ratio)) ** 0.5
        out.append(round((1.0 - k) / (1.0 + k), 4))  # to four places, as the table writes colours
    return tuple(out)


# Crowns and hedges: to the camera, a canopy of LEAF (above); to the LiDAR, green leaves reflect
# 0.45-0.55 on the NIR plateau (PROSPECT; ECOSTRESS library), 0.50 x 2/3 = 0.33 for a leaf
# volume. Porosity: leaf-on crowns of urban broadleaf trees pass 10-30 % of direct sunlight (crown
# transmissivity, Heisler 1986, Urban Ecology 9); a beam crosses a crown's closed mesh twice, so
# 0.45 per crossing passes 0.45^2 = 0.2 of them.
FOLIAGE = Material("foliage", canopy_reflectance(LEAF), 0.33, incidence_exponent=0.0, porosity=0.45)
# Belts of shrubs (simgen.scenery._green): the same leaves, drawn as one closed mass. Their
# overlapping shrubs' shells would have a beam cross a leaf surface about every metre inside the
# belt (0.45 passing each time: 0.09 of the beams left after 3 m), each crossing one more Embree
# query (a fifth more rays a sweep: 1.66 times the bare query against the 1.5 allowed, with
# this porosity set to 0.45, `benchmarks/bench_lidar.py`); drawn as the mass's outer surface
# instead (porosity 0), a beam ends where it enters, not up to a metre or two deeper. Its shadows
# are full (a closed mass).
SHRUB_MASS = replace(FOLIAGE, porosity=0.0)
# Galvanised steel poles: bright zinc reflects about 0.55 at 905 nm, mostly specularly;
# weathered (zinc patina) and diffuse, about 0.4.
METAL = Material("pole", (0.30, 0.31, 0.33), 0.40)
# Weathered wood: 0.4-0.5 at 905 nm (dry wood is NIR-bright; ECOSTRESS library).
FENCE = Material("fence", (0.35, 0.30, 0.25), 0.45)
# Traffic sign faces: retro-reflective sheeting of EN 12899-1 class RA1, the minimum for German
# signs (VwV-StVO), as the plates: R_A at observation 0.2 deg, entrance 5 deg of white 70, yellow
# 50, red 14.5, blue 4 cd lx^-1 m^-2, times pi; the fall with the entrance angle as the plates'
# (cos^6). Colours: DIN 6171's traffic colours RAL 9016, 1023, 3020 and 5017, linear RGB.
SIGN_WHITE = Material("sign_white", (0.88, 0.87, 0.82), 220.0, incidence_exponent=6.0)
SIGN_YELLOW = Material("sign_yellow", (0.93, 0.46, 0.0), 157.0, incidence_exponent=6.0)
SIGN_RED = Material("sign_red", (0.60, 0.002, 0.002), 45.6, incidence_exponent=6.0)
SIGN_BLUE = Material("sign_blue", (0.002, 0.040, 0.165), 12.6, incidence_exponent=6.0)
# Brick and rendered plaster: 0.4-0.6 at 905 nm (ECOSTRESS library: red brick about 0.45,
# limestone render about 0.6); the lower end.
FACADE_REFLECTIVITY = 0.45
# Windows (the façade tiles' windows, simgen.textures.Window; the LiDAR reads them through
# simgen.lidar.windows). Double glazing with a thermal low-E coat: such coats pass the solar near
# infrared (they turn from transmitting to reflecting near 2 um; solar-control coats, turning
# near 0.7 um, would reflect the beam), so a unit passes about what two clear float panes do,
# 0.9 each at 905 nm (see GLASS below), less a few per cent for the coat: 0.75 one way at normal
# incidence, falling towards grazing as four faces' Fresnel loss rises. The beam ends inside:
# on a curtain (the textiles' 0.55, `textile_reflectivity`), or in the room, whose walls, floor
# and furniture are read as clutter (no fall-off with incidence, as a car's interior): no measured
# figure for a room as a whole was found; white wall paint reads 0.8-0.9 at 905 nm (titanium
# white), wood and textiles 0.4-0.6 (FENCE, clothes), dark floors and voids less: 0.5.
WINDOW_TRANSMITTANCE = 0.75
ROOM_REFLECTIVITY = 0.5
CURTAIN_REFLECTIVITY = 0.55

# --- Vehicles. -----------------------------------------------------------------------------
# Green-tinted automotive glass: ferrous iron absorbs around 1000 nm, so a pane passes about
# 0.6 of a 905 nm beam (clear float glass about 0.9). A pane has no diffuse echo of its own (a
# clean pane reflects specularly, 4 % per surface, away from the sensor unless it faces it
# exactly): the beam goes on (simgen.lidar.scan). Its `reflectivity` is what a beam that ends
# inside the vehicle reads (on the seats, head restraints and trim the camera's glass shows, or
# below the window line): upholstery and trim, mostly black or dark grey, 0.13 by the
# carbon-black rule for a dark grey (0.1) and seen as clutter (no fall-off with incidence).
# What the camera sees through a pane is that cabin: upholstery and trim (the dark grey
# below) lit only by the daylight its glazing lets in, then seen through a pane again. The
# glazing is about a quarter of the cabin's enclosing surface and passes about 0.75 of the
# light (UN ECE R43 asks at least 0.70 of the panes a driver looks through): 0.25 x 0.75 x 0.75,
# about 0.14 of the colour the trim would have under the open sky. Lit as an outside surface,
# sun included, a rear window would read as a bright band where a photographed one is dark.
CABIN_LIGHT = 0.14
GLASS = Material("glass", tuple(CABIN_LIGHT * c for c in (0.04, 0.05, 0.07)),
                 nir_reflectivity((0.1, 0.1, 0.1)), incidence_exponent=0.0, transmittance=0.6)
# Tyre rubber is filled with carbon black: about 0.03 at 905 nm.
TYRE = Material("tyre", (0.02, 0.02, 0.02), 0.03)
# Licence plates: retro-reflective sheeting (ISO 7591), of the order of EN 12899-1 class RA1
# (white, observation 0.2 deg: R_A 70 cd lx^-1 m^-2 at 5 deg entrance, 30 at 30 deg):
# pi x 70 = 220, and cos^6 gives the fall to 30/70 at 30 deg.
PLATE = Material("plate", (0.90, 0.90, 0.85), 220.0, incidence_exponent=6.0)
# Headlamps: a clear lens over an aluminised reflector (aluminium: 0.86 at 905 nm, a mirror).
# No measured LiDAR figure was found; a diffuse 0.60, kept from before.
HEADLIGHT = Material("headlight", (0.95, 0.95, 0.90), 0.60)
# Rear lamps hold a red reflex reflector (UN ECE R3 class IA: at least 300 mcd/lx at 20'
# observation, 0 deg entrance, 100 at 20 deg): over the lens's face on a car's back, 0.28 x 0.20
# m (simgen.meshes.TAIL_LAMP_*), pi x 0.3 / 0.056 = 17; cos^18 gives the fall to a third at 20
# deg. Where the lens wraps round the corner and along the side no reflector faces out: a red
# lens over an aluminised reflector, read as the headlamp (TAIL_LENS).
TAILLIGHT = Material("taillight", (0.60, 0.02, 0.02), 17.0, incidence_exponent=18.0)
TAIL_LENS = Material("taillight", (0.60, 0.02, 0.02), 0.60)
FRAME = paint_material("bike_frame", (0.15, 0.15, 0.17))
# Bumpers, sills, grilles and mirror housings of black plastic: polypropylene coloured with carbon
# black, the pigment that absorbs the NIR too (see above): by the rule above, 0.07 (Levinson et
# al. 2005: carbon black < 0.1 across the NIR). The same for signal heads (black housings and
# background boards).
TRIM = paint_material("trim", (0.03, 0.03, 0.03))
# Wheel rims: cast aluminium alloy, clear-coated or silver-painted (aluminium flakes in a clear
# binder), or steel rims painted silver. Polished aluminium reflects about 0.86 at 905 nm, but
# mostly specularly, away from the sensor; a light grey, 0.55 by the rule above. The camera sees
# the rim's face whole: on an alloy, about half of it spokes and half openings onto the dark brake
# and hub (five- and multi-spoke wheels, read off makers' wheel images; no survey), so its mean
# colour is about half the silver's. The LiDAR keeps the silver's reading (a beam that meets a
# spoke reads it; one through an opening ends on the brake disc, steel, no darker at 905 nm).
RIM = replace(paint_material("rim", (0.60, 0.61, 0.63)), color=(0.31, 0.315, 0.325))


def signal_lens(color) -> Material:
    """A traffic signal's lens (lit or dark by its colour): coloured polycarbonate over a lamp and
    its reflector, or over an LED board. No measured 905 nm figure found: the headlamps' 0.60."""
    return Material("signal_lens", tuple(float(c) for c in color), HEADLIGHT.reflectivity)


def textile_reflectivity(color) -> float:
    """Clothes at 905 nm. Cotton and polyester fibres scatter strongly in the NIR and most textile
    dyes are transparent there (which is why camouflage fabrics need NIR-absorbing dyes): dyed
    fabrics reflect about 0.5-0.7 whatever their colour; only near-blacks, dyed with carbon or
    sulphur black, absorb, to about 0.2. 0.55, falling to 0.2 as the brightest channel falls
    from 0.15 to 0.08 (black)."""
    v = max(float(c) for c in color)
    return round(0.2 + (0.55 - 0.2) * min(max((v - 0.08) / 0.07, 0.0), 1.0), 4)


def skin_reflectivity(color) -> float:
    """Human skin at 905 nm: melanin absorbs less in the NIR than in the visible, so skin tones
    spread only from about 0.4 (darkest) to about 0.6 (lightest) (e.g. Cooksey & Allen,
    NIST skin reflectance library); linear in the tone's brightest channel, 0.30 to 0.80."""
    v = max(float(c) for c in color)
    return round(0.4 + 0.2 * min(max((v - 0.3) / 0.5, 0.0), 1.0), 4)
