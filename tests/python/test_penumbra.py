"""The penumbra Python module (python/module.cpp), run by ctest with PYTHONPATH at the
build's module, PENUMBRA_VALIDATION=1 (any validation message fails), PENUMBRA_CLI and
PENUMBRA_TEST_TMP. Plain unittest: python3 tests/python/test_penumbra.py"""
import os
import pathlib
import shutil
import signal
import subprocess
import threading
import time
import unittest

import numpy as np

import penumbra

TMP = os.path.join(os.environ.get("PENUMBRA_TEST_TMP", "/tmp"), "python")
CITY = os.path.join(TMP, "city.glb")  # 20k triangles with the generator's camera and sun (glTF keeps them)
SIZE = (160, 120)
CAMERA = {"position": [150, 120, 150], "target": [0, 0, 0], "fov": 50}
SUN = "directional direction=-1,-1,-0.5 intensity=2"
SPOT = "spot position=0,100,0 direction=0,-1,0 outer_cone=40 intensity=30000"
SPOT_DICT = {"type": "spot", "position": np.array([0.0, 100.0, 0.0]), "direction": (0, -1, 0), "outer_cone": 40, "intensity": 3e4}


def setUpModule():
    os.makedirs(TMP, exist_ok=True)
    penumbra.generate("city", CITY, triangles=20_000)


def tearDownModule():
    assert penumbra.validation_messages() == 0, "Vulkan validation messages were printed above"


def cli_error(*args):
    """The CLI's one-line error for these arguments (without 'penumbra: error: ')."""
    run = subprocess.run([os.environ["PENUMBRA_CLI"], *args], capture_output=True, text=True)
    assert run.returncode == 1, (run.returncode, run.stderr)
    line = run.stderr.strip().splitlines()[-1]
    assert line.startswith("penumbra: error: "), line
    return line[len("penumbra: error: "):]


def luminance(image):
    return image[..., :3].mean(axis=-1)


class Render(unittest.TestCase):
    def test_render_returns_float_rgba_with_shadows_darker_than_lit(self):
        image = penumbra.render(CITY, size=SIZE, shadows="srt", camera=CAMERA, lights=[SUN])
        self.assertEqual(image.shape, (SIZE[1], SIZE[0], 4))
        self.assertEqual(image.dtype, np.float32)
        self.assertTrue(np.isfinite(image).all())

        renderer = penumbra.Renderer(CITY)
        renderer.set_camera(CAMERA)
        renderer.set_lights([SUN])
        same = renderer.render(size=SIZE, shadows="srt", gbuffer=True)
        np.testing.assert_array_equal(same, image)
        visibility = renderer.gbuffer["visibility"]
        self.assertEqual(visibility.shape, (SIZE[1], SIZE[0]))
        lit, shadowed = visibility == 1, visibility == 0
        self.assertGreater(lit.sum(), 100)
        self.assertGreater(shadowed.sum(), 100)
        self.assertLess(luminance(image)[shadowed].mean(), 0.5 * luminance(image)[lit].mean())

    def test_renderer_renders_frames_with_other_lights_without_reloading(self):
        model = os.path.join(TMP, "reload.glb")
        shutil.copy(CITY, model)
        renderer = penumbra.Renderer(model)
        os.remove(model)  # loaded once: later frames cannot read it again
        renderer.set_lights(["directional direction=-1,-2,-0.5"])
        first = renderer.render(size=SIZE, shadows="sm")
        renderer.set_lights([{"type": "directional", "direction": [1, -2, 0.5]}])
        second = renderer.render(size=SIZE, shadows="sm")
        self.assertEqual(first.shape, second.shape)
        self.assertGreater(np.abs(first - second).max(), 0.1)
        renderer.set_lights(["directional direction=-1,-2,-0.5"])
        np.testing.assert_array_equal(renderer.render(size=SIZE, shadows="sm"), first)

    def test_light_strings_and_dicts_are_the_same_lights(self):
        renderer = penumbra.Renderer(CITY)
        renderer.set_camera(CAMERA)
        renderer.set_lights([SPOT])
        from_string = renderer.render(size=SIZE, shadows="sm")
        renderer.set_lights([SPOT_DICT])
        np.testing.assert_array_equal(renderer.render(size=SIZE, shadows="sm"), from_string)

    def test_stats_are_a_dict_like_the_cli_stats_file(self):
        renderer = penumbra.Renderer(CITY)
        self.assertIsNone(renderer.stats)
        renderer.render(size=SIZE, shadows="srt")
        stats = renderer.stats
        for key in ("device", "triangles", "width", "height", "lights", "shadows", "covered_pixels", "pip_pixels",
                    "rays", "passes", "cull", "views", "gpu_ms", "frame_ms"):
            self.assertIn(key, stats)
        self.assertEqual((stats["width"], stats["height"]), SIZE)
        self.assertEqual(stats["shadows"], "srt")
        self.assertEqual(stats["triangles"], 20_000)
        self.assertGreater(stats["covered_pixels"], 0)
        self.assertIn("shade_ms", stats["passes"])
        self.assertEqual(stats["device"]["name"], renderer.device["name"])
        self.assertFalse(stats["srt_traced_all"])  # a first frame is srt's own

    def test_srt_frames_trace_every_pixel_only_when_allowed(self):
        renderer = penumbra.Renderer(CITY)
        renderer.set_camera(CAMERA)
        renderer.set_lights([SUN])
        for adaptive in (False, True):
            ways = []
            for _ in range(18):
                renderer.render(size=SIZE, shadows="srt", srt_adaptive=adaptive)
                ways.append((renderer.stats["srt_traced_all"], renderer.stats["srt_probe"]))
                if renderer.stats["srt_probe"]:
                    break
            if adaptive:  # one probe of a frame that traces every pixel, within the settle frames
                self.assertEqual(ways[-1], (True, True), ways)
            else:
                self.assertNotIn(True, [way for pair in ways for way in pair], ways)


class Errors(unittest.TestCase):
    def test_a_bad_model_path_raises_the_cli_message(self):
        path = os.path.join(TMP, "missing.ply")
        with self.assertRaises(penumbra.Error) as raised:
            penumbra.render(path, size=SIZE)
        self.assertIsInstance(raised.exception, RuntimeError)
        self.assertIn(path, str(raised.exception))
        self.assertEqual(str(raised.exception), cli_error("render", path, "-o", os.path.join(TMP, "missing.png")))

    def test_bad_lights_and_settings_raise_the_cli_messages(self):
        renderer = penumbra.Renderer(CITY)
        with self.assertRaises(penumbra.Error) as raised:
            renderer.set_lights(["spot outer_cone=95"])
        self.assertEqual(str(raised.exception), cli_error("render", CITY, "--light", "spot outer_cone=95"))
        with self.assertRaises(penumbra.Error) as raised:
            renderer.render(size=SIZE, shadows="rt")
        self.assertEqual(str(raised.exception), cli_error("render", CITY, "--shadows", "rt"))
        with self.assertRaisesRegex(penumbra.Error, r"^lights\[1\]: unknown light key 'size'$"):
            renderer.set_lights([SPOT, {"type": "point", "size": 2}])
        with self.assertRaisesRegex(penumbra.Error, r"^camera: 'fov' must be a number$"):
            renderer.set_camera({"fov": "wide"})
        with self.assertRaisesRegex(penumbra.Error, r"^size: "):
            renderer.render(size=(0, 10))


class Preprocess(unittest.TestCase):
    def test_preprocess_writes_a_file_that_renders_like_the_source(self):
        output = pathlib.Path(TMP) / "city.penumbra"  # paths: str or os.PathLike
        stats = penumbra.preprocess(CITY, output)
        self.assertGreater(os.path.getsize(output), 0)
        self.assertEqual(stats["triangles"], 20_000)
        self.assertGreater(stats["clusters"], 0)
        # The city's parts are closed and its ground is not; every part stands on the ground, within the
        # ray offset of another surface, so no cluster is flagged closed (preprocess/README.md, "Clearance").
        self.assertGreater(stats["closed_triangles"], 0)
        self.assertEqual(stats["closed_cluster_triangles"], 0)
        self.assertLess(stats["closed_triangles"], stats["triangles"])
        source = penumbra.render(CITY, size=SIZE, camera=CAMERA, lights=[SPOT])
        preprocessed = penumbra.render(output, size=np.array(SIZE), camera=CAMERA, lights=[SPOT])
        np.testing.assert_array_equal(preprocessed, source)
        with self.assertRaisesRegex(penumbra.Error, "the output must end in .penumbra"):
            penumbra.preprocess(CITY, os.path.join(TMP, "city.bin"))
        # Without camera and lights: the glTF's own, which the file keeps.
        np.testing.assert_array_equal(penumbra.render(output, size=SIZE), penumbra.render(CITY, size=SIZE))
        # And colors=False renders the same here (the generated city has no colours).
        np.testing.assert_array_equal(penumbra.render(output, size=SIZE, colors=False), penumbra.render(CITY, size=SIZE))

    def test_streamed_and_distributed_preprocessing(self):
        ply = os.path.join(TMP, "streamed_city.ply")
        penumbra.generate("city", ply, triangles=20_000)
        stats = penumbra.preprocess(ply, os.path.join(TMP, "streamed_city.penumbra"), memory_limit=64)
        self.assertEqual(stats["triangles"], 20_000)
        self.assertGreaterEqual(stats["chunks"], 1)
        chunks = [os.path.join(TMP, f"streamed_city.chunk{i}") for i in range(3)]
        for i, chunk in enumerate(chunks):
            penumbra.preprocess(ply, chunk, chunk=f"{i}/3", memory_limit=64)
        merged = penumbra.merge(list(reversed(chunks)), os.path.join(TMP, "streamed_city_merged.penumbra"))
        self.assertEqual(merged["triangles"], 20_000)
        with self.assertRaisesRegex(penumbra.Error, "chunk 1 of 3 is missing"):
            penumbra.merge([chunks[0], chunks[2]], os.path.join(TMP, "streamed_city_bad.penumbra"))
        with self.assertRaisesRegex(penumbra.Error, "cannot be combined with memory_limit"):
            penumbra.preprocess(ply, os.path.join(TMP, "x.penumbra"), memory_limit=64, simplify=0.5)

    def test_ctrl_c_stops_a_preprocessing_call_and_leaves_no_file(self):
        ply = os.path.join(TMP, "interrupted_scan.ply")
        penumbra.generate("scan", ply, triangles=600_000)
        interrupted = 0
        # As in a terminal: a background job (ctest under nohup, some CI) inherits SIGINT ignored.
        previous = signal.signal(signal.SIGINT, signal.default_int_handler)
        self.addCleanup(signal.signal, signal.SIGINT, previous)
        for kwargs in ({}, {"memory_limit": 32}):
            output = os.path.join(TMP, "interrupted_scan.penumbra")
            if os.path.exists(output):
                os.remove(output)
            # SIGINT to this process 0.3 s into the call: Python's handler raises KeyboardInterrupt
            # in the main thread, which the call's progress checks see while the build runs.
            timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
            returned = False
            timer.start()
            try:
                with self.assertRaises(KeyboardInterrupt, msg=str(kwargs)):
                    penumbra.preprocess(ply, output, threads=2, **kwargs)
                    returned = True
                    time.sleep(5)  # finished before the signal (a fast machine): it lands here
            finally:
                timer.cancel()
            if returned:
                continue
            interrupted += 1
            self.assertFalse(os.path.exists(output), kwargs)
            self.assertEqual([f for f in os.listdir(TMP) if f.startswith("interrupted_scan.penumbra.")], [], kwargs)
        self.assertGreater(interrupted, 0, "every call ended before its signal: nothing was tested")

    def test_ground_exposure_tone_curve_and_exr_layers(self):
        frames = {}
        for ground in ("off", "below"):  # the city is wide: "auto" adds no ground to it
            renderer = penumbra.Renderer(CITY, ground=ground)
            renderer.set_camera(CAMERA)
            renderer.set_lights([SUN])
            frames[ground] = (renderer.render(size=SIZE, gbuffer=True), renderer.gbuffer)
        lowest = {g: gbuffer["position"][..., 1][gbuffer["position"][..., 3] != 0].min() for g, (_, gbuffer) in frames.items()}
        self.assertLess(lowest["below"], lowest["off"])

        image, gbuffer = frames["below"]
        plain, filmic = os.path.join(TMP, "plain.png"), os.path.join(TMP, "filmic.png")
        penumbra.write_image(image, plain)
        penumbra.write_image(image, filmic, exposure="auto", tonemap="filmic")
        self.assertNotEqual(pathlib.Path(plain).read_bytes(), pathlib.Path(filmic).read_bytes())
        exr = os.path.join(TMP, "layers.exr")
        try:
            penumbra.write_image(image, exr, layers={"visibility.light0": gbuffer["visibility"]})
            self.assertGreater(os.path.getsize(exr), 0)
        except penumbra.Error as error:  # a build without OpenImageIO writes .png only, and says so
            self.assertIn("no OpenImageIO", str(error))
        with self.assertRaisesRegex(penumbra.Error, "--tonemap reinhard"):
            penumbra.write_image(image, plain, tonemap="reinhard")
        with self.assertRaisesRegex(penumbra.Error, "need an .exr output"):
            penumbra.write_image(image, plain, layers={"pip": gbuffer["visibility"]})
        with self.assertRaisesRegex(penumbra.Error, "--ground"):
            penumbra.Renderer(CITY, ground="sideways")


if __name__ == "__main__":
    unittest.main()
