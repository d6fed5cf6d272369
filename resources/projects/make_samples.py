"""Write the sample projects in this folder from the validated models (run after a schema change):

    .venv/bin/python resources/projects/make_samples.py
"""
from workbench.isp.params import ISPParams
from workbench.optics.params import OpticsParams
from workbench.project import PROJECTS_DIR, ExperimentParams, Project, save_project
from workbench.render.params import FogParams, NightParams, RenderParams, WorldParams
from workbench.scene.city import CityRecipe, PoseParams, TunnelParams
from workbench.scene.params import SceneParams, WavelengthParams
from workbench.sensor.params import SENSOR_PRESETS

VIDEO_MAX_EXPOSURE_S = 1 / 30      # a 30 fps automotive video camera exposes at most one frame time
# The Macbeth sample's own exposure: its brightest pixel (white 9.5) at 90 % of the swing, so no patch
# clips (the paper's rule, mean at 40 %, clipped 12.4 % of its pixels and turned 9 patches pure white).
# Its experiments keep the paper's rule: ExperimentParams' method and level, which they read instead.
CHART_SENSOR = SENSOR_PRESETS["paper_table1"].updated(auto_exposure_method="brightest", auto_exposure_level=0.9)


def main() -> None:
    paper = Project(
        name="paper_camera",
        description="The paper's camera (Table 1): 640x480, 3 um pixel, 1 mV/s dark, 1 mV read noise, 1 V swing, "
                    "44 deg FOV pinhole, 8 bits; Macbeth chart under D65 at a mean sensor illuminance of 1000 lux; "
                    "bilinear demosaic, Macbeth/D65 colour matrix keeping greys grey, white balance on the near-grey "
                    "pixels (the paper's gray world tints this chart's greys: its mean is not grey), blown "
                    "highlights rendered white, sRGB. Auto-exposed with the brightest pixel (white 9.5) at 90 % "
                    "of the swing so no patch clips; the exposure experiment keeps the paper's rule (mean at "
                    "40 % of the swing, the experiment block).",
        scene=SceneParams(kind="macbeth", illuminant="D65", distance_m=10.0, adjust_illuminance_lux=1000.0),
        sensor=CHART_SENSOR,
        isp=ISPParams(illuminant_correction="gray_pixels"))
    samples = [
        paper,
        paper.updated(
            name="uniform_d65_isetcam_pixel",
            description="ISETCam's default sensor (2.8 um, GRBG, analog) on a uniform D65 field of 100 cd/m2 at f/4.",
            scene=SceneParams(kind="uniform", illuminant="D65", mean_luminance_cd_m2=100.0, distance_m=1.2),
            sensor=SENSOR_PRESETS["isetcam_default"]),
        paper.updated(
            name="hdr_tunnel_auto_rccc",
            description="An automotive RCCC sensor (MT9V024-like, no IR cut) facing a dark tunnel with a bright exit "
                        "(1e6:1); wavelengths 400-1000 nm because the clear channel sees the near infrared.",
            scene=SceneParams(kind="hdr_tunnel", distance_m=30.0,
                              wavelengths=WavelengthParams(start_nm=400, stop_nm=1000, step_nm=20)),
            optics=OpticsParams(focal_length_mm=4.0, f_number=2.0),
            sensor=SENSOR_PRESETS["auto_rccc"].updated(auto_exposure_method="brightest", auto_exposure_level=0.9),
            isp=ISPParams(illuminant_correction="none")),
        paper.updated(
            name="slanted_edge_diffraction_f8",
            description="The paper's sensor behind diffraction-limited f/8 optics on an ISO 12233 slanted edge.",
            scene=SceneParams(kind="slanted_edge", distance_m=10.0, adjust_illuminance_lux=1000.0),
            optics=OpticsParams(model="diffraction_limited", f_number=8.0),
            sensor=SENSOR_PRESETS["paper_table1"]),      # the paper's rule: the edge's bright side does not clip
    ]
    city = paper.updated(
        name="city_paper_camera",
        description="The paper's four-block city (2x2 blocks of 100 m; cars, pedestrians, buses, trees, lamps, "
                    "benches, mailboxes placed by rule) seen by the paper's camera 1.5 m above the road, about "
                    "10 m from a target object, rendered spectrally with Mitsuba 3 under daylight.",
        scene=SceneParams(kind="city", distance_m=10.0, adjust_illuminance_lux=None),
        sensor=SENSOR_PRESETS["paper_table1"],          # the paper's rule (no chart white in a street)
        city=CityRecipe(seed=1), pose=PoseParams(mode="target", seed=1), render=RenderParams())
    samples += [
        city,
        city.updated(
            name="city_automotive_lens_full_model",
            description="The city frame through the automotive 2.4 mm lens (44 deg on the paper's sensor) at f/2.8, "
                        "traced inside Mitsuba for every camera ray (the full model).",
            optics=OpticsParams(model="raytrace", lens_file="automotive.2.4mm.json", f_number=2.8)),
    ]
    day = city.render.daylight

    def textured(wet_road_fraction: float = 0.05, **world) -> WorldParams:
        """Procedural materials (worn asphalt, stained concrete, bricks, grass with soil, puddles) and
        vehicle paint under a clear coat."""
        return WorldParams(materials="procedural", wet_road_fraction=wet_road_fraction, paint="clearcoat", **world)

    detailed = city.city.updated(asset_detail="detailed")   # wheels, glass, lights, mirrors, plates; posed people
    # kerbs parked; ground to the horizon, with distant blocks on it
    street = detailed.updated(n_parked_cars=12, horizon_field_m=3000.0, skyline_distance_m=250.0)

    samples += [
        city.updated(
            name="city_day_clear_sky",
            city=street,
            description="The city under a clear Perez/Preetham sky (brighter toward the sun and the horizon, "
                        "spectral to 1100 nm) with see-through, Fresnel-reflecting window glass and procedural "
                        "materials (worn and patched asphalt, stained concrete, bricks, grass with soil; dry road).",
            render=RenderParams(daylight=day.updated(sky_model="perez"), world=textured(0.0, glass="dielectric"))),
        city.updated(
            name="city_low_sun",
            city=street,
            description="The city with the sun 5 deg above the horizon in the east: "
                        "a long shadow, reddened sun (air mass ~10) and a Perez sky bright around the sun; "
                        "procedural materials with wet patches on 5 % of the road.",
            render=RenderParams(daylight=day.updated(sun_elevation_deg=5.0, sun_azimuth_deg=90.0,
                                                     sky_model="perez"), world=textured(0.05))),
        city.updated(
            name="city_overcast",
            city=street,
            description="The city under a CIE overcast sky (no direct sun; 30 % of the clear-sky global irradiance); "
                        "procedural materials with puddles on 15 % of the road.",
            render=RenderParams(daylight=day.updated(sky_model="overcast"), world=textured(0.15))),
        city.updated(
            name="city_night",
            city=street,
            description="The city at night: high-pressure sodium street lamps (15,000 lm), LED head-lights and red "
                        "tail-lights on every moving car (parked cars dark), a 0.02 cd/m2 sky glow, each lamp sampled by its light at "
                        "the shading point (fewer fireflies); the auto_rccc sensor (no IR cut) sees "
                        "the sodium 819 nm line; procedural materials with puddles on 10 % of the road. As an "
                        "automotive night camera: f/2, exposure at most 1/30 s (30 fps video; auto-exposure would "
                        "otherwise open to seconds) and the MT9V024's largest analog gain, 4x.",
            optics=city.optics.updated(f_number=2.0),
            sensor=SENSOR_PRESETS["auto_rccc"].updated(max_exposure_s=VIDEO_MAX_EXPOSURE_S, analog_gain=4.0),
            render=RenderParams(world=textured(0.10, lighting="night", night=NightParams(light_selection="shading")))),
        city.updated(
            name="city_fog",
            city=street,
            description="The city in fog of 150 m visibility (extinction 3.912/150 per m, albedo 0.98, forward "
                        "scattering g = 0.85) in a 60 m deep layer, under an overcast sky; procedural materials "
                        "with puddles on 15 % of the road; Koschmieder's law per pixel with a measured "
                        "in-scattering profile (fog.model 'volumetric' renders the medium itself, ~10^3 times the cost).",
            render=RenderParams(daylight=day.updated(sky_model="overcast"),
                                world=textured(0.15, fog=FogParams(visibility_m=150.0, height_m=60.0)))),
        city.updated(
            name="city_tunnel",
            description="Inside a 150 m road tunnel by day, 20-60 m before the exit (the HDR case): concrete walls "
                        "and roof, a continuous line of glowing LED luminaires over the centre line (1.5 m lenses "
                        "end to end every 1.6 m, 4,000 lm each: 2,500 lm per metre; CIE 88 interior zone, road "
                        "~6 cd/m2) against the sunlit street beyond the portal; blocks of 180 m "
                        "so the segment holds the tunnel; procedural materials (dry road); the auto_rccc sensor "
                        "(MT9V024-like: 10-bit linear ADC, no IR cut; exposure at most 1/30 s).",
            city=street.updated(block_size_m=180.0, tunnel=TunnelParams(length_m=150.0)),
            pose=PoseParams(mode="tunnel", tunnel_view="exit", seed=1),
            sensor=SENSOR_PRESETS["auto_rccc"].updated(max_exposure_s=VIDEO_MAX_EXPOSURE_S),
            render=RenderParams(world=textured(0.0))),
    ]
    tunnel_exit = samples[-1]
    samples.append(tunnel_exit.updated(
        name="city_tunnel_entrance",
        description="The same road tunnel seen from the sunlit street 20-60 m before its entrance (the other HDR "
                    "case: exposed for the street, the portal is a dark hole whose inside a 10-bit linear sensor "
                    "cannot show); the auto_rccc sensor (exposure at most 1/30 s).",
        pose=tunnel_exit.pose.updated(tunnel_view="entrance")))
    # one stratified chunk of 100 = 10² spp (multijitter takes squares as they are): median render
    # noise ≤ ⅓ of the shot noise at EV −4, and ≤ ⅔ at the 90th percentile and on object edges
    # (workbench dataset-noise); six camera poses per loaded city
    DETECTION_RENDER = RenderParams(representation="sensor", spp=100, chunk_spp=100, preview_spp=100,
                                    sampler="multijitter", world=textured(0.05))
    detection = city.updated(
        name="city_detection_quick",
        description="Data for the detection experiments (workbench experiment isp|exposure, quick and standard "
                    "profiles): the paper's city made denser (60 cars, 120 pedestrians, 8 buses, 6 trucks per "
                    "arrangement) seen from 1.5 m in a lane, aimed at a target object 6-20 m away; 320x240 pixels "
                    "of 6 um (the paper's 3 um pixel binned 2x2, so the 44 deg field of view is kept), rendered in "
                    "the sensor's own channels at 100 spp in one stratified (multijitter) chunk, so the render "
                    "noise stays below a third of the photon shot noise at EV -4 (workbench dataset-noise), with "
                    "procedural materials (puddles on 5 % of the road); six camera poses per city arrangement "
                    "(every third city is a test city); exposure biases -4...+4 EV in steps of 1. "
                    "Render its data set with: workbench dataset city_detection_quick --frames 612 --out DIR "
                    "(102 cities: the standard profile's 408 training and 204 test frames; the quick one needs 120)",
        city=detailed.updated(n_cars=60, n_pedestrians=120, n_buses=8, n_trucks=6),
        pose=PoseParams(mode="target", seed=1, target_distance_range_m=(6.0, 20.0), poses_per_arrangement=6),
        sensor=SENSOR_PRESETS["paper_table1"].updated(rows=240, cols=320, pixel_pitch_um=6.0),
        render=DETECTION_RENDER,
        experiment=ExperimentParams(ev_biases=[float(ev) for ev in range(-4, 5)]))
    samples += [
        detection,
        detection.updated(
            name="city_detection_paper",
            description="The detection experiments' paper profile: city_detection_quick at the paper's 640x480 "
                        "with its 3 um pixel (44 deg), 100 spp in one multijitter chunk, six poses per city. "
                        "Render ~3,000 frames (2,000 train / 1,000 test).",
            sensor=SENSOR_PRESETS["paper_table1"]),
    ]
    # The dense detection city at night, seen by an automotive night camera: the MT9V024-like sensor
    # (6 um, 10 bits, 25,455 e- well) binned to 320x240 so the 44 deg field of view is kept, f/2,
    # exposure at most 1/30 s, analog gain 4x, as city_night. The MT9V024 is sold with a Bayer and
    # with an RCCC filter: the two variants differ only in the CFA and in the IR-cut filter a colour
    # camera carries (RCCC cameras have none), so a detector trained on each says which sees more.
    night_camera = SENSOR_PRESETS["auto_rccc"].updated(rows=240, cols=320, max_exposure_s=VIDEO_MAX_EXPOSURE_S,
                                                       analog_gain=4.0)
    night_detection = detection.updated(
        name="city_detection_night",
        description="Night data for the detection experiments, Bayer variant (city_detection_night_rccc is the RCCC "
                    "one): city_detection_quick's dense city (60 cars with LED head-lights and red tail-lights, "
                    "120 pedestrians, 8 buses, 6 trucks per arrangement) at night under its high-pressure sodium "
                    "street lamps (15,000 lm) and a 0.02 cd/m2 sky glow, the same six camera poses per city aimed at "
                    "objects 6-20 m away; an automotive night camera (MT9V024-like 6 um pixels, 10 bits, 320x240 "
                    "so the 44 deg field of view is kept, f/2, exposure at most 1/30 s, analog gain 4x) with an RGGB "
                    "filter and an IR-cut filter at 650 nm; head-lights are SAE J1383 low beams; rendered in the "
                    "sensor's own channels (one multijitter chunk of 100 spp, lamps picked per shading point: render "
                    "noise at EV -4 meets the data sets' criterion (worst of 3 frames: median 0.10, p90 0.15, edges "
                    "0.13 of the shot noise, between two independent renders) at 1.6-2.0x a day frame's CPU time, "
                    "issue 33); "
                    "procedural materials (puddles on 5 % of the road); exposure biases -4...+4 EV. Render its data "
                    "set with: workbench dataset city_detection_night --frames 612 --out DIR",
        optics=detection.optics.updated(f_number=2.0),
        sensor=night_camera.updated(cfa_pattern="RGGB", ir_cut_file="sensors/ir_cut_650.csv"),
        render=DETECTION_RENDER.updated(spp=100, chunk_spp=100, preview_spp=100,
                                        world=textured(0.05, lighting="night",
                                                       night=NightParams(light_selection="shading"))))
    samples += [
        night_detection,
        night_detection.updated(
            name="city_detection_night_rccc",
            description="city_detection_night seen through the RCCC variant of its night camera (red + three clear "
                        "pixels, no IR-cut filter, so the clear pixels also take the sodium lamps' 819 nm line): "
                        "the same cities, poses, lamps and exposure rule, only the filters differ, and it renders "
                        "one chunk of 144 spp, not 100: a clear pixel collects ~3x the electrons of a Bayer pixel, so "
                        "the same render noise weighs sqrt(3) more against its shot noise. At 144 spp its render noise "
                        "at EV -4 meets the data sets' criterion (worst of 3 frames: median 0.19, p90 0.28, edges 0.23 "
                        "of the shot noise, between two independent renders) at 1.8-2.3x a day frame's CPU time "
                        "(issue 33). Render its data set with: workbench dataset city_detection_night_rccc --frames "
                        "612 --out DIR",
            sensor=night_camera,
            render=night_detection.render.updated(spp=144, chunk_spp=144, preview_spp=144)),
    ]
    for project in samples:
        save_project(project, PROJECTS_DIR / f"{project.name}.json")


if __name__ == "__main__":
    main()
