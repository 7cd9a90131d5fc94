//! `/v1/scenes` end to end: startup loading, listing, posting, deleting.

use crate::common::{TINY_SCENE, error_json, error_of, spawn_app_with_scenes};
use reqwest::StatusCode;
use serde_json::{Value, json};

fn tiny_named(name: &str) -> Value {
    let mut doc: Value = serde_json::from_str(TINY_SCENE).unwrap();
    doc["name"] = json!(name);
    doc
}

#[tokio::test]
async fn startup_loads_good_scenes_and_skips_broken_ones() {
    let app = spawn_app_with_scenes(
        &[("tiny.json", TINY_SCENE), ("broken.json", "{\"shapes\": [")],
        |_| {},
    )
    .await;
    let health: Value = app.get("/health").await.json().await.unwrap();
    assert_eq!(health["scenes"], 1);

    let list: Value = app.get("/v1/scenes").await.json().await.unwrap();
    let ids: Vec<_> = list
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["id"].clone())
        .collect();
    assert_eq!(ids, [json!("tiny")]);

    let response = app.get("/v1/scenes/tiny").await;
    assert_eq!(response.status(), StatusCode::OK);
    let summary: Value = response.json().await.unwrap();
    assert_eq!(summary["resolution"], json!([8, 8]));
    assert_eq!(summary["source"], "file");
    assert_eq!(summary["shapes"], 1);
}

#[tokio::test]
async fn posted_scene_can_be_read_replaced_and_deleted() {
    let app = spawn_app_with_scenes(&[], |_| {}).await;
    let response = app.post_json("/v1/scenes", &tiny_named("posted")).await;
    assert_eq!(response.status(), StatusCode::CREATED);
    let summary: Value = response.json().await.unwrap();
    assert_eq!(summary["id"], "posted");
    assert_eq!(summary["source"], "uploaded");

    // The id is taken: refused naming it, unless the post replaces it.
    let taken = app.post_json("/v1/scenes", &tiny_named("posted")).await;
    assert_eq!(taken.status(), StatusCode::CONFLICT);
    assert_eq!(
        error_of(taken).await,
        ("scene_exists".into(), Some("name".into()))
    );
    let again = app
        .post_json("/v1/scenes?replace=true", &tiny_named("posted"))
        .await;
    assert_eq!(again.status(), StatusCode::OK);
    assert_eq!(app.get("/v1/scenes/posted").await.status(), StatusCode::OK);

    let deleted = app.delete("/v1/scenes/posted").await;
    assert_eq!(deleted.status(), StatusCode::NO_CONTENT);
    let gone = app.get("/v1/scenes/posted").await;
    assert_eq!(gone.status(), StatusCode::NOT_FOUND);
    assert_eq!(error_of(gone).await.0, "not_found");
    let again = app.delete("/v1/scenes/posted").await;
    assert_eq!(again.status(), StatusCode::NOT_FOUND);
}

#[tokio::test]
async fn bad_scene_documents_are_422_naming_the_field() {
    let app = spawn_app_with_scenes(&[], |_| {}).await;
    let unnamed: Value = serde_json::from_str(TINY_SCENE).unwrap();
    let mut bad_material = tiny_named("bad");
    bad_material["shapes"][0]["material"] = json!("nonexistent");
    let mut escaping = tiny_named("escape");
    escaping["shapes"] =
        json!([{"type": "obj", "filename": "../outside.obj", "material": "white"}]);
    let cases = [
        (unnamed, "name"),
        (tiny_named("has space"), "name"),
        (bad_material, "shapes[0].material"),
        (escaping, "shapes[0].filename"),
    ];
    for (doc, field) in cases {
        let response = app.post_json("/v1/scenes", &doc).await;
        assert_eq!(
            response.status(),
            StatusCode::UNPROCESSABLE_ENTITY,
            "{field}"
        );
        let (code, got) = error_of(response).await;
        assert_eq!(code, "invalid_field");
        assert_eq!(got.as_deref(), Some(field));
    }
    let health: Value = app.get("/health").await.json().await.unwrap();
    assert_eq!(health["scenes"], 0);
}

const CORNELL_XML: &str = include_str!("../../scenes/cornell-box.xml");

#[tokio::test]
async fn mitsuba_xml_scenes_load_at_startup_and_by_post() {
    let app = spawn_app_with_scenes(
        &[
            ("box.json", TINY_SCENE),
            ("box.xml", CORNELL_XML),
            ("only.xml", CORNELL_XML),
        ],
        |_| {},
    )
    .await;
    // An XML file beside a JSON file of the same stem gets `<stem>-xml`.
    for id in ["box", "box-xml", "only"] {
        let response = app.get(&format!("/v1/scenes/{id}")).await;
        assert_eq!(response.status(), StatusCode::OK, "{id}");
    }
    let xml_summary: Value = app.get("/v1/scenes/box-xml").await.json().await.unwrap();
    assert_eq!(xml_summary["resolution"], json!([256, 256]));
    // A Mitsuba document has no name of its own: a file's is its stem.
    assert_eq!(xml_summary["name"], "box");

    let post_xml = |query: &'static str, content_type: &'static str| {
        app.client
            .post(app.url(&format!("/v1/scenes{query}")))
            .header("content-type", content_type)
            .body(CORNELL_XML)
            .send()
    };
    let created = post_xml("?id=posted-xml", "application/xml").await.unwrap();
    assert_eq!(created.status(), StatusCode::CREATED);
    let summary: Value = created.json().await.unwrap();
    assert_eq!(summary["id"], "posted-xml");
    // ... and a posted one's is its id.
    assert_eq!(summary["name"], "posted-xml");
    assert_eq!(summary["source"], "uploaded");

    let no_id = post_xml("", "text/xml").await.unwrap();
    assert_eq!(no_id.status(), StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(error_of(no_id).await.1.as_deref(), Some("id"));

    let bad_id = post_xml("?id=a%20b", "application/xml").await.unwrap();
    assert_eq!(bad_id.status(), StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(error_of(bad_id).await.1.as_deref(), Some("id"));

    let plain = post_xml("?id=x", "text/plain").await.unwrap();
    assert_eq!(plain.status(), StatusCode::UNSUPPORTED_MEDIA_TYPE);
    // The route takes both, so its 415 names both.
    let (body, _) = error_json(plain).await;
    let message = body["error"]["message"].as_str().unwrap();
    assert!(
        message.contains("application/json") && message.contains("application/xml"),
        "{message}"
    );

    let broken = app
        .client
        .post(app.url("/v1/scenes?id=broken"))
        .header("content-type", "application/xml")
        .body("<scene version=\"3.0.0\"><shape type=\"teapot\"/></scene>")
        .send()
        .await
        .unwrap();
    assert_eq!(broken.status(), StatusCode::UNPROCESSABLE_ENTITY);
    // Nothing already loaded is lost.
    assert_eq!(app.get("/v1/scenes/only").await.status(), StatusCode::OK);
}

/// `?id=` belongs to XML bodies; with JSON it would be ambiguous beside the
/// document's `name`, so it is refused naming `id` and nothing is replaced.
#[tokio::test]
async fn id_query_with_a_json_scene_is_refused() {
    let app = spawn_app_with_scenes(&[("kept.json", TINY_SCENE)], |_| {}).await;
    let before: Value = app.get("/v1/scenes/kept").await.json().await.unwrap();
    for query in ["?id=kept", "?id=other"] {
        let response = app
            .client
            .post(app.url(&format!("/v1/scenes{query}")))
            .json(&tiny_named("kept"))
            .send()
            .await
            .unwrap();
        assert_eq!(
            response.status(),
            StatusCode::UNPROCESSABLE_ENTITY,
            "{query}"
        );
        let (code, field) = error_of(response).await;
        assert_eq!(
            (code.as_str(), field.as_deref()),
            ("invalid_field", Some("id"))
        );
    }
    let after: Value = app.get("/v1/scenes/kept").await.json().await.unwrap();
    assert_eq!(after["source"], "file");
    assert_eq!(after, before);
    assert_eq!(
        app.get("/v1/scenes/other").await.status(),
        StatusCode::NOT_FOUND
    );
}

/// `?param.NAME=VALUE` sets a posted Mitsuba scene's `$NAME` (like
/// `mitsuba -D`); bad names, repeats and JSON scenes are refused, naming
/// the parameter.
#[tokio::test]
async fn posted_xml_takes_its_parameters_from_the_query() {
    let app = spawn_app_with_scenes(&[("box.json", TINY_SCENE)], |_| {}).await;
    let xml = r#"<scene version="3.0.0"><default name="res" value="8"/>
        <sensor type="perspective"><film type="hdrfilm">
          <integer name="width" value="$res"/><integer name="height" value="$res"/>
        </film></sensor>
        <shape type="rectangle"/></scene>"#;
    let post = |query: &str, content_type: &'static str, body: String| {
        app.client
            .post(app.url(&format!("/v1/scenes{query}")))
            .header("content-type", content_type)
            .body(body)
            .send()
    };
    let resolution = |response: reqwest::Response| async move {
        assert!(response.status().is_success(), "{}", response.status());
        response.json::<Value>().await.unwrap()["resolution"].clone()
    };
    let plain = post("?id=p", "application/xml", xml.into()).await.unwrap();
    assert_eq!(resolution(plain).await, json!([8, 8]));
    let set = post(
        "?id=p&replace=true&param.res=16",
        "application/xml",
        xml.into(),
    )
    .await
    .unwrap();
    assert_eq!(resolution(set).await, json!([16, 16]));
    for (query, field) in [
        ("?id=q&param.r%20s=1", "param.r s"),
        ("?id=q&param.=1", "param."),
        ("?id=q&param.res=1&param.res=2", "param.res"),
        ("?id=q&param.res=x", "value"),
    ] {
        let refused = post(query, "application/xml", xml.into()).await.unwrap();
        assert_eq!(
            refused.status(),
            StatusCode::UNPROCESSABLE_ENTITY,
            "{query}"
        );
        let named = error_of(refused).await.1.unwrap_or_default();
        assert!(named.contains(field), "{query}: {named}");
    }
    let json_scene = post(
        "?param.res=16",
        "application/json",
        TINY_SCENE.replacen('{', r#"{"name": "t2","#, 1),
    )
    .await
    .unwrap();
    assert_eq!(json_scene.status(), StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(error_of(json_scene).await.1.as_deref(), Some("param.res"));
}
