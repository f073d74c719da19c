import penumbra

penumbra.generate("city", "city.glb", triangles=20_000)    # a small test scene with its camera and sun
image = penumbra.render("city.glb", size=(320, 240), shadows="srt")
print(image.shape, image.dtype)                            # (240, 320, 4) float32, linear RGBA
penumbra.write_image(image, "city.png")

renderer = penumbra.Renderer("city.glb")                   # load once, render many frames
for x in (-1.0, 1.0):
    renderer.set_lights([f"directional direction={x},-2,-0.5 intensity=2"])
    frame = renderer.render(size=(320, 240), shadows="srt")
    print(frame[..., :3].mean(), renderer.stats["rays"], renderer.stats["passes"]["trace_ms"])
