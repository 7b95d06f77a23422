//! `KHR_draco_mesh_compression` as loaded: a stream that cannot be decoded is refused naming the
//! primitive (`tracer/src/scene/gltf_loader/draco.rs` tests real streams; the page decodes one
//! in `tests/cli/web.rs`).

use super::*;

/// A primitive compressed with Draco, the extension required (as in the Draco-compressed
/// LittlestTokyo): its accessors have no buffer views, the compressed data is a buffer view of
/// its own. Draco is supported (`gltf_loader/draco.rs`, whose tests load real streams); this
/// one is a bare 16-byte header, so the file is refused naming the primitive and the extension.
#[test]
fn undecodable_draco_stream_is_refused_by_name() {
    let json = r#"{
  "asset": {"version": "2.0"},
  "extensionsUsed": ["KHR_draco_mesh_compression"],
  "extensionsRequired": ["KHR_draco_mesh_compression"],
  "scene": 0,
  "scenes": [{"nodes": [0]}],
  "nodes": [{"mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "extensions": {
      "KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}}]}],
  "buffers": [{"byteLength": 16, "uri": "data:application/octet-stream;base64,RFJBQ08CAgEBAAAAAAAAAA=="}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 16}],
  "accessors": [
    {"componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
    {"componentType": 5123, "count": 3, "type": "SCALAR"}
  ]
}"#;
    let err = load_str(json).unwrap_err();
    assert!(matches!(err, SceneError::Malformed(_)), "{err:?}");
    let message = err.to_string();
    assert!(
        message.contains("mesh 0 primitive 0")
            && message.contains("KHR_draco_mesh_compression")
            && message.contains("cannot be decoded"),
        "{message}"
    );
}
