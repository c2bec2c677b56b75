"""The scene model, GL-free: a scene file's description (scene.json: networks, camera, lights,
settings), cameras, images and their sidecars, labels and display modes. The GL runtime
(``inshade.runtime``) draws what this describes; nothing here opens a context."""
